// preintegrated's light through thin parts (common/transmittance.glsl) in two halves: here, in
// texture space, the part that depends on the lights, sum_i far_face_light (the irradiance entering
// the far face A = P - h Ng, times its soft shadows: 2 PCF lookups per light), per texel of the
// thickness map's layout (tsd/uv_space.vert rasterises the mesh there; the fragment's uv_ts is its
// texel's centre, where the bilinear thickness read is the texel's own h), kept between frames until
// the lights, the shadow atlas or the bake change (dermis.techniques.preintegrated); skin.frag
// multiplies it, read bilinearly, by the slab law T(h) / A at the pixel's own bilinear h, as
// transmitted_irradiance does (the law is steep in h: interpolating it texel to texel instead drew
// the texels on the back-lit helix, up to 7% of the image's maximum at 512 px). A camera-only frame
// then reads one texel per pixel instead of evaluating the shadows. Stored with a weight (alpha 1
// where the texel has a far face, 0 elsewhere and off the mesh) for a normalised read: a pixel at
// the bake's or a chart's edge takes the mean of its texels that hold a far face.
#include "common/transmittance.glsl"

in vec3 v_world;
in vec3 v_normal;
out vec4 f_far_face;

void main() {
    vec2 uv_ts = gl_FragCoord.xy / vec2(textureSize(uThicknessMap, 0));
    float h;
    vec3 T_h;
    if (uTranslucencyStrength <= 0.0 || !thin_part_at(uv_ts, h, T_h)) {
        f_far_face = vec4(0.0);
        return;
    }
    vec3 Ng = normalize(v_normal);
    vec3 A = v_world - Ng * (h / uMmPerUnit);
    vec3 X = vec3(0.0);
    for (int i = 0; i < uLightCount; ++i) X += far_face_light(i, A, Ng);
    f_far_face = vec4(X, 1.0);
}
