/* DO NOT EDIT: two_link_arm module, generated from template control.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build two_link_arm`. */
/* Flatness-based control (docs/algorithms.md): v from the reference flags and the pole-placement
 * gains on each chain, u = G(x)^-1 (v - F(x)) with the model parameters as a runtime vector.
 * Near a singularity it refuses: |det G(x)| below SINGULAR_RTOL times its value at the model's
 * nominal state (DET_NOMINAL, in the header) gives ERR_SINGULAR and leaves u, v alone.
 * Declared input limits clamp u (and v = F + G u follows); *saturated counts clamped inputs. */
#include <string.h>
#include "two_link_arm_internal.h"

#define NX TWO_LINK_ARM_NX
#define NY TWO_LINK_ARM_NY

/* Nominal parameter values, in model order: m1, m2, l1, l2, Jm1, Jm2, k_e, k_d, R, L, g. */
const real two_link_arm_params_default[TWO_LINK_ARM_NP] = {
    0.4, /* m1 [kg] */
    0.2, /* m2 [kg] */
    0.25, /* l1 [m] */
    0.2, /* l2 [m] */
    0.01, /* Jm1 [kg*m^2] */
    0.01, /* Jm2 [kg*m^2] */
    0.5, /* k_e [N*m/A] */
    0.05, /* k_d [N*m*s/rad] */
    2.0, /* R [ohm] */
    0.005, /* L [H] */
    9.81 /* g [m/s^2] */
};

int two_link_arm_control(const real x[NX], const real flags[TWO_LINK_ARM_NFLAGS],
                         const real gains[NX], const real params[TWO_LINK_ARM_NP],
                         real u[TWO_LINK_ARM_NU], real v[NY], uint32_t* saturated)
{
    real ul[NY], vl[NY], det[1], nsat[1], mag;
    real w[TWO_LINK_ARM_KERN_CONTROL_SZ_W];
    if (!x || !flags || !gains || !params || !u) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!two_link_arm_finite(x, NX) || !two_link_arm_finite(flags, TWO_LINK_ARM_NFLAGS) ||
        !two_link_arm_finite(gains, NX) || !two_link_arm_finite(params, TWO_LINK_ARM_NP)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    (void)two_link_arm_kern_control(x, flags, gains, params, ul, vl, det, nsat, w);
    if (!two_link_arm_finite(det, 1)) {
        return TWO_LINK_ARM_ERR_SINGULAR;
    }
    mag = (det[0] < (real)0) ? -det[0] : det[0];
    if (!(mag >= ((TWO_LINK_ARM_SINGULAR_RTOL) * (TWO_LINK_ARM_DET_NOMINAL)))) {
        return TWO_LINK_ARM_ERR_SINGULAR;
    }
    if (!two_link_arm_finite(ul, NY) || !two_link_arm_finite(vl, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    (void)memcpy(u, ul, sizeof(ul));
    if (v != NULL) {
        (void)memcpy(v, vl, sizeof(vl));
    }
    if (saturated != NULL) {
        *saturated += (uint32_t)nsat[0];
    }
    return TWO_LINK_ARM_OK;
}

int two_link_arm_gains(const real lambda[NY], real gains[NX])
{
    static const int degree[NY] = TWO_LINK_ARM_CHAIN_DEGREES;
    static const int offset[NY] = TWO_LINK_ARM_CHAIN_OFFSETS;
    real out[NX];
    int j, i;
    if (!lambda || !gains) {
        return TWO_LINK_ARM_ERR_ARG;
    }
    if (!two_link_arm_finite(lambda, NY)) {
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    for (j = 0; j < NY; j++) {
        real binom = (real)1, power = (real)1;
        for (i = 1; i <= degree[j]; i++) { /* k_i = C(r, i) lambda^i */
            binom = binom * ((real)degree[j] - (real)i + (real)1) / (real)i;
            power = power * lambda[j];
            out[offset[j] + i - 1] = binom * power;
        }
    }
    if (!two_link_arm_finite(out, NX)) { /* lambda^r overflowed */
        return TWO_LINK_ARM_ERR_NONFINITE;
    }
    (void)memcpy(gains, out, sizeof(out));
    return TWO_LINK_ARM_OK;
}
