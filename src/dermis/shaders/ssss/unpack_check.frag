// Test only (tests/test_ssss_kernel.py): ssss_unpack_half2 of each uint of uWords, as two floats.
#include "ssss/packing.glsl"
uniform usampler2D uWords;
layout(location = 0) out vec2 f_halves;
void main() {
    f_halves = ssss_unpack_half2(texelFetch(uWords, ivec2(gl_FragCoord.xy), 0).r);
}
