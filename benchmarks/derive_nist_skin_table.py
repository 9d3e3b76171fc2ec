"""Derive src/dermis/data/nist_skin_reflectance_ita.csv from the NIST skin reflectance data set.

    python benchmarks/derive_nist_skin_table.py PATH/TO/NIST.csv > src/dermis/data/nist_skin_reflectance_ita.csv

Input: "Reference Data Set of Human Skin Reflectance", Cooksey, Allen & Tsai, J. Res. NIST 122:26
(2017), doi:10.6028/jres.122.026, data doi:10.18434/M38597 (a US government work: public
domain): 100 subjects, inner right forearm, hemispherical reflectance factor with the specular
part included (integrating sphere, 8 deg incidence), 250-2500 nm every 3 nm; the "Average"
column of each subject (the mean of three measurements) is used.

Each subject is classed by its Individual Typology Angle ITA = atan((L* - 50) / b*) (Chardon et
al. 1991, Int. J. Cosmet. Sci. 13:191) of CIELAB under D65 and the CIE 1931 2 deg observer, in
the six skin-colour categories of Del Bino et al. 2006 (Pigment Cell Res. 19:606): very light
> 55 deg, light 41-55, intermediate 28-41, tan 10-28, brown -30-10, dark < -30 (no NIST subject
is "dark"). The table holds each category's mean and sample standard deviation at 400-700 nm
every 10 nm (linear interpolation of the 3 nm data).
"""

import sys

import numpy as np

CATEGORIES = (("very_light", 55, 90), ("light", 41, 55), ("intermediate", 28, 41), ("tan", 10, 28),
              ("brown", -30, 10))


def main(path: str) -> None:
    import colour

    data = np.loadtxt(path, skiprows=8, delimiter=",", encoding="latin1", usecols=[4 * i for i in range(101)])
    wavelength, reflectance = data[:, 0], data[:, 1:].T
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    ita = []
    for spectrum in reflectance:
        sd = colour.SpectralDistribution(dict(zip(wavelength, spectrum)))
        sd = sd.interpolate(colour.SpectralShape(250, 2500, 1)).trim(colour.SpectralShape(360, 780, 1))
        lab = colour.XYZ_to_Lab(colour.sd_to_XYZ(sd, cmfs, d65) / 100.0, white)
        ita.append(np.degrees(np.arctan2(lab[0] - 50.0, lab[2])))
    ita = np.array(ita)
    grid = np.arange(400, 701, 10)
    sampled = np.array([np.interp(grid, wavelength, s) for s in reflectance])
    columns, counts = [], []
    for name, low, high in CATEGORIES:
        members = (ita > low) & (ita <= high)
        counts.append(f"{name} {members.sum()}")
        columns.append((sampled[members].mean(axis=0), sampled[members].std(axis=0, ddof=1)))
    print("# subjects per category: " + ", ".join(counts))
    print("wavelength_nm," + ",".join(f"{n}_mean,{n}_sd" for n, _, _ in CATEGORIES))
    for i, w in enumerate(grid):
        print(f"{w}," + ",".join(f"{m[i]:.4f},{s[i]:.4f}" for m, s in columns))


if __name__ == "__main__":
    main(sys.argv[1])
