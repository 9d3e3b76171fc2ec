// The output transform on the GPU, the twin of dermis/output.py (tested against it):
// linear HDR radiance -> exposure (stops) -> tone map -> sRGB encoding, for display.
// uImage holds an image whose row 0 is the TOP row (uploaded as numpy arrays are), so v is flipped.
in vec2 v_uv;
out vec4 frag_color;

uniform sampler2D uImage;
uniform float uExposureScale;  // 2^exposure
uniform int uTonemap;          // 0: ACES (Narkowicz 2015), 1: linear (clamp)

// Narkowicz 2015, "ACES Filmic Tone Mapping Curve": a fit of the ACES RRT + ODT.
vec3 aces_narkowicz(vec3 x) {
    x = max(x, vec3(0.0));
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

// IEC 61966-2-1 sRGB encoding of linear values in [0, 1].
vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    vec3 lo = c * 12.92;
    vec3 hi = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(c, vec3(0.0031308)));
}

void main() {
    vec3 x = texture(uImage, vec2(v_uv.x, 1.0 - v_uv.y)).rgb * uExposureScale;
    vec3 y = (uTonemap == 0) ? aces_narkowicz(x) : clamp(x, 0.0, 1.0);
    frag_color = vec4(linear_to_srgb(y), 1.0);
}
