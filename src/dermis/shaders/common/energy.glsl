// Energy conservation between the specular layer and the diffuse skin beneath it
// (d'Eon & Luebke 2007, 14.3.1 "Energy conservation"), shared by every skin technique.
// The table holds a(cos, m), the integral of KS_Skin_Specular (rho_s = 1) over the hemisphere,
// which like d'Eon's BRDF carries no 1/pi; dermis renders physical radiance (the convention of
// dermis/techniques/shared.py), so the fraction the specular reflects is rho_s * a / pi, and
// 1 - rho_s * a / pi is what enters (cosTheta = N.L) or leaves (cosTheta = N.V) the skin.
#include "common/brdf.glsl"

float energy_transmitted(float rho_s, float cosTheta, float m) {
    return 1.0 - rho_s * rho_dt_lookup(uSpecularTables, cosTheta, m) * INV_PI;
}
