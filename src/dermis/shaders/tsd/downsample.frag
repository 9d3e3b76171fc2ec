// 2x2 coverage-weighted box reduction to the next level (half resolution). Wide Gaussians hold
// no fine detail, so they are blurred at reduced resolution (d'Eon & Luebke 2007, 14.4.3;
// Jimenez & Gutierrez 2008). Colour is normalised by coverage; alpha is the mean coverage.
uniform sampler2D uSource;
in vec2 v_uv;
out vec4 f_color;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 2;
    ivec2 size = textureSize(uSource, 0);
    vec3 sum = vec3(0.0), plain = vec3(0.0);
    float sa = 0.0;
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x) {
            vec4 c = texelFetch(uSource, min(p + ivec2(x, y), size - 1), 0);
            sum += c.rgb * c.a;
            plain += c.rgb;
            sa += c.a;
        }
    f_color = vec4(sa > 1e-6 ? sum / sa : plain * 0.25, sa * 0.25);
}
