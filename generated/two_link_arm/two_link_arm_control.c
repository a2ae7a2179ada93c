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
const real two_link_arm_params_default[TWO_LINK_ARM_NP_SLOTS] = {
    [TWO_LINK_ARM_P_m1] = 0.4, /* [kg] */
    [TWO_LINK_ARM_P_m2] = 0.2, /* [kg] */
    [TWO_LINK_ARM_P_l1] = 0.25, /* [m] */
    [TWO_LINK_ARM_P_l2] = 0.2, /* [m] */
    [TWO_LINK_ARM_P_Jm1] = 0.01, /* [kg*m^2] */
    [TWO_LINK_ARM_P_Jm2] = 0.01, /* [kg*m^2] */
    [TWO_LINK_ARM_P_k_e] = 0.5, /* [N*m/A] */
    [TWO_LINK_ARM_P_k_d] = 0.05, /* [N*m*s/rad] */
    [TWO_LINK_ARM_P_R] = 2.0, /* [ohm] */
    [TWO_LINK_ARM_P_L] = 0.005, /* [H] */
    [TWO_LINK_ARM_P_g] = 9.81 /* [m/s^2] */
};

/* The header's non-integer constants as objects, and the zeta index of each flat output
 * (internal). */
const real two_link_arm_ts = TWO_LINK_ARM_TS;
const uint8_t two_link_arm_chain_angle[NY] = TWO_LINK_ARM_CHAIN_ANGLE;
const uint8_t two_link_arm_heads[NY] = TWO_LINK_ARM_CHAIN_OFFSETS;

int two_link_arm_control(const real x[NX], const real flags[TWO_LINK_ARM_NFLAGS],
                         const real gains[TWO_LINK_ARM_NZ],
                         const real params[TWO_LINK_ARM_NP_SLOTS], real u[TWO_LINK_ARM_NU],
                         real v[NY], uint32_t* saturated)
{
    real ul[NY];
    real vl[NY];
    real det[1];
    real nsat[1];
    real w[TWO_LINK_ARM_KERN_CONTROL_SZ_W];
    int rc = TWO_LINK_ARM_OK;
    if ((x == NULL) || (flags == NULL) || (gains == NULL) || (params == NULL) || (u == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    } else if (!two_link_arm_finite(x, NX) || !two_link_arm_finite(flags, TWO_LINK_ARM_NFLAGS) ||
               !two_link_arm_finite(gains, TWO_LINK_ARM_NZ) ||
               !two_link_arm_finite(params, TWO_LINK_ARM_NP)) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    } else {
        (void)two_link_arm_kern_control(x, flags, gains, params, ul, vl, det, nsat, w);
        if (two_link_arm_finite(det, 1) == 0) {
            rc = TWO_LINK_ARM_ERR_SINGULAR;
        }
    }
    if (rc == TWO_LINK_ARM_OK) {
        real mag = (det[0] < (real)0) ? -det[0] : det[0];
        if (!(mag >= ((TWO_LINK_ARM_SINGULAR_RTOL) * (TWO_LINK_ARM_DET_NOMINAL)))) {
            rc = TWO_LINK_ARM_ERR_SINGULAR;
        } else if (!two_link_arm_finite(ul, NY) || !two_link_arm_finite(vl, NY)) {
            rc = TWO_LINK_ARM_ERR_NONFINITE;
        } else {
            (void)memcpy(u, ul, sizeof(ul));
            if (v != NULL) {
                (void)memcpy(v, vl, sizeof(vl));
            }
            if (saturated != NULL) {
                *saturated += (uint32_t)nsat[0];
            }
        }
    }
    return rc;
}

int two_link_arm_gains(const real lambda[NY], real gains[TWO_LINK_ARM_NZ])
{
    static const int degree[NY] = TWO_LINK_ARM_CHAIN_DEGREES;
    static const int offset[NY] = TWO_LINK_ARM_CHAIN_OFFSETS;
    real out[TWO_LINK_ARM_NZ] = {0};
    int j;
    int i;
    int rc = TWO_LINK_ARM_OK;
    if ((lambda == NULL) || (gains == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    } else if (!two_link_arm_finite(lambda, NY)) {
        rc = TWO_LINK_ARM_ERR_NONFINITE;
    } else {
        for (j = 0; j < NY; j++) {
            if (!(lambda[j] > (real)0)) { /* poles at -lambda: 0 or below is not stable */
                rc = TWO_LINK_ARM_ERR_ARG;
            }
        }
    }
    if (rc == TWO_LINK_ARM_OK) {
        for (j = 0; j < NY; j++) {
            real binom = (real)1;
            real power = (real)1;
            for (i = 1; i <= degree[j]; i++) { /* k_i = C(r, i) lambda^i */
                binom = (binom * (((real)degree[j] - (real)i) + (real)1)) / (real)i;
                power = power * lambda[j];
                out[(offset[j] + i) - 1] = binom * power;
            }
        }
        if (two_link_arm_finite(out, TWO_LINK_ARM_NZ) != 0) {
            (void)memcpy(gains, out, sizeof(out));
        } else { /* lambda^r overflowed */
            rc = TWO_LINK_ARM_ERR_NONFINITE;
        }
    }
    return rc;
}

int two_link_arm_broadcast(const real u[TWO_LINK_ARM_NU], const real v[NY], const real x[NX],
                           real w[TWO_LINK_ARM_NW])
{
    int rc = TWO_LINK_ARM_OK;
    if ((u == NULL) || (v == NULL) || (x == NULL) || (w == NULL)) {
        rc = TWO_LINK_ARM_ERR_ARG;
    } else {
        (void)memcpy(w, u, sizeof(real) * (size_t)TWO_LINK_ARM_NU);
    }
    return rc;
}
