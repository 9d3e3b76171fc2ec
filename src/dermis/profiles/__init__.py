"""Diffusion profiles from physics (no GL): sum-of-Gaussians, dipole, multipole, photon beam
diffusion, Christensen-Burley, the spectral skin model and a Monte Carlo reference."""

from dermis.profiles.gaussians import SumOfGaussians, deon_skin, gaussian_2d

__all__ = ["SumOfGaussians", "deon_skin", "gaussian_2d"]
