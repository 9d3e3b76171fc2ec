"""Baseline technique ``lambert``: Lambert diffuse + normalised Blinn-Phong specular.

What it approximates: nothing of subsurface scattering: light leaves where it enters, so skin looks
hard and dry (sharp shadow edges, no red bleeding, no translucency). It exists as the baseline every
skin technique must visibly beat, and it exercises the shared machinery: shadow atlas with PCF soft
shadows, normal mapping, lights, environment (SH irradiance) and the output transform.
Inputs: the scene's albedo (linear), normal map, specular map, roughness m (mapped to a Blinn-Phong
exponent), rho_s. With ``[scene] interreflection`` (default) it adds albedo / pi x T, the bounce light
between skin surfaces (E_b and its higher orders: the Renderer's shared pass, dermis.gl.interreflection.SharedBounce),
so that it is the no-SSS counterpart of a path tracer's diffuse render, which has interreflection.
Shader: shaders/lambert/lambert.frag.
"""

from __future__ import annotations

import moderngl

from dermis.errors import DermisError
from dermis.techniques.base import Frame, Technique, draw_mesh, draw_surfaces
from dermis.techniques.shared import (INTERREFLECTION_DEFINE, LightCountPrograms, OutputMode, bind_interreflection,
                                      prepare_interreflection)


class Lambert(Technique):
    name = "lambert"
    description = "Lambert diffuse + Blinn-Phong specular, PCF soft shadows (baseline, no scattering)"

    def __init__(self, renderer):
        super().__init__(renderer)
        # one program per light count, its light loop unrolled (LightCountPrograms), and per light
        # signature (the kinds and shadow kernels as constants: the same floats; round 24, sig24)
        self.programs = LightCountPrograms(self.ctx, "common/mesh.vert", "lambert/lambert.frag",
                                           signature=True).compile_for(renderer.scene)
        # with the shared one bounce (the Renderer's, made with the first technique that reads it)
        self._programs_bounce = LightCountPrograms(self.ctx, "common/mesh.vert", "lambert/lambert.frag", {INTERREFLECTION_DEFINE: 1},
                                                   signature=True).compile_for(renderer.scene)
        renderer.interreflection  # the shared one bounce: made with the first technique that reads it
        self.prog = None  # when set (benchmarks and tests swap shaders in), drawn instead of the above


    def light_programs(self, scene, bounce: bool) -> LightCountPrograms:
        """The per-count programs (LightCountPrograms) the light loop is drawn from for ``scene``,
        with or without the shared bounce."""
        return self._programs_bounce if bounce else self.programs

    def override_light_program(self, prog) -> None:
        """Draw ``prog`` instead of the per-count programs (None: back to them); benchmarks, tests."""
        self.prog = prog

    def render(self, frame: Frame, output_mode: int = OutputMode.FULL) -> None:
        if output_mode != OutputMode.FULL:
            raise DermisError(f"technique '{self.name}' renders only the full image (output mode {OutputMode.FULL.name.lower()})")
        bounce = prepare_interreflection(frame)  # albedo / pi times the shared bounce E_b
        prog = self.prog if self.prog is not None else self.light_programs(frame.scene, bounce)(frame.lights.count, frame.lights.lights)
        with frame.timer("lambert"):
            frame.target.use()
            self.ctx.enable(moderngl.DEPTH_TEST)
            self.ctx.disable(moderngl.CULL_FACE)
            if bounce:
                bind_interreflection(frame, prog)
            draw_mesh(frame, prog)
        frame.passes_run.append("lambert")
        draw_surfaces(frame, output_mode)  # the non-skin surfaces, with depth testing

    def release(self):
        self.programs.release()
        self._programs_bounce.release()
