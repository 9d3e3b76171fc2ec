// Ambient light from the environment as 9 spherical-harmonic coefficients of its IRRADIANCE
// (Ramamoorthi & Hanrahan 2001, "An Efficient Representation for Irradiance Environment Maps",
// eq. 13): E(n) = sum_lm A_l L_lm Y_lm(n), with the A_l folded into uEnvSH on the CPU.
uniform vec3 uEnvSH[9];

vec3 environment_irradiance(vec3 n) {
    vec3 e = uEnvSH[0] * 0.282095
           + uEnvSH[1] * 0.488603 * n.y + uEnvSH[2] * 0.488603 * n.z + uEnvSH[3] * 0.488603 * n.x
           + uEnvSH[4] * 1.092548 * n.x * n.y + uEnvSH[5] * 1.092548 * n.y * n.z
           + uEnvSH[6] * 0.315392 * (3.0 * n.z * n.z - 1.0)
           + uEnvSH[7] * 1.092548 * n.x * n.z + uEnvSH[8] * 0.546274 * (n.x * n.x - n.y * n.y);
    return max(e, vec3(0.0));
}
