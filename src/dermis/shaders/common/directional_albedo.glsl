// The skin's directional albedo (dermis.profiles.directional_albedo; issue 12, round 7): light that
// enters a half-space at a shallow angle scatters near the surface and escapes before it is
// absorbed, light that enters head-on goes deeper and is absorbed more (Chandrasekhar 1960, ch. IV).
// A diffusion profile returns the same light at every angle (a Lambertian exit); the radiative
// transfer returns R(mu) = A k(mu), k(mu) = 1 + c(A) (2/3 - mu), mu the cosine in air. The linear
// form keeps the hemispherical normalisation exactly (int_0^1 2 mu (2/3 - mu) dmu = 0), so light
// that is uniform over the hemisphere (the ambient) gets the factor 1 on average; by reciprocity the
// same factor weights the light that enters (mu = N.L) and the light that leaves (mu = N.V).
// c(A): least-squares fits of the random walk (isotropic, index 1.4, refraction at entry, Fresnel at
// exit) per total reflectance A, tabulated in data/directional_albedo.json by
// `python -m dermis.profiles.directional_albedo --table`; tests/test_directional_albedo.py checks that
// these constants are that table's. c(0) = the lowest row's, c(1) = 0 (a medium that absorbs nothing
// returns all light at every angle).
const int DA_ROWS = 15;
const float DA_A[DA_ROWS] = float[DA_ROWS](0.0, 0.0164, 0.04028, 0.08073, 0.11407, 0.16636, 0.22845, 0.30777, 0.38344, 0.46915, 0.52862, 0.63051, 0.71909, 0.80946, 1.0);
const float DA_C[DA_ROWS] = float[DA_ROWS](0.1779, 0.1779, 0.1778, 0.1555, 0.1416, 0.1307, 0.1204, 0.1017, 0.0819, 0.0696, 0.0586, 0.0486, 0.0327, 0.0213, 0.0);

float directional_c(float A) {
    float a = clamp(A, 0.0, 1.0);
    for (int i = 1; i < DA_ROWS; ++i) {
        if (a <= DA_A[i]) {
            float t = (a - DA_A[i - 1]) / max(DA_A[i] - DA_A[i - 1], 1e-6);
            return mix(DA_C[i - 1], DA_C[i], t);
        }
    }
    return DA_C[DA_ROWS - 1];
}

vec3 directional_c(vec3 A) {
    return vec3(directional_c(A.r), directional_c(A.g), directional_c(A.b));
}

// k(mu) per channel for the coefficients c (vec3(0): a Lambertian entry or exit)
vec3 directional_factor(vec3 c, float mu) {
    return 1.0 + c * (2.0 / 3.0 - clamp(mu, 0.0, 1.0));
}
