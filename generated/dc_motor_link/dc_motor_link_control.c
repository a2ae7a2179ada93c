/* DO NOT EDIT: dc_motor_link module, generated from template control.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* Flatness-based control (docs/algorithms.md): v from the reference flags and the pole-placement
 * gains on each chain, u = G(x)^-1 (v - F(x)) with the model parameters as a runtime vector.
 * Near a singularity it refuses: |det G(x)| below SINGULAR_RTOL times its value at the model's
 * nominal state (DET_NOMINAL, in the header) gives ERR_SINGULAR and leaves u, v alone.
 * Declared input limits clamp u (and v = F + G u follows); *saturated counts clamped inputs. */
#include <string.h>
#include "dc_motor_link_internal.h"

#define NX DC_MOTOR_LINK_NX
#define NY DC_MOTOR_LINK_NY

/* Nominal parameter values, in model order: L, R, k_e, k_d, J, m, g, l. */
const real dc_motor_link_params_default[DC_MOTOR_LINK_NP_SLOTS] = {
    [DC_MOTOR_LINK_P_L] = 0.005, /* [H] */
    [DC_MOTOR_LINK_P_R] = 2.0, /* [ohm] */
    [DC_MOTOR_LINK_P_k_e] = 0.5, /* [N*m/A] */
    [DC_MOTOR_LINK_P_k_d] = 0.05, /* [N*m*s/rad] */
    [DC_MOTOR_LINK_P_J] = 0.02, /* [kg*m^2] */
    [DC_MOTOR_LINK_P_m] = 0.3, /* [kg] */
    [DC_MOTOR_LINK_P_g] = 9.81, /* [m/s^2] */
    [DC_MOTOR_LINK_P_l] = 0.25 /* [m] */
};

/* The header's non-integer constants as objects, and the zeta index of each flat output
 * (internal). */
const real dc_motor_link_ts = DC_MOTOR_LINK_TS;
const uint8_t dc_motor_link_chain_angle[NY] = DC_MOTOR_LINK_CHAIN_ANGLE;
const uint8_t dc_motor_link_heads[NY] = DC_MOTOR_LINK_CHAIN_OFFSETS;

int dc_motor_link_control(const real x[NX], const real flags[DC_MOTOR_LINK_NFLAGS],
                          const real gains[DC_MOTOR_LINK_NZ],
                          const real params[DC_MOTOR_LINK_NP_SLOTS], real u[DC_MOTOR_LINK_NU],
                          real v[NY], uint32_t* saturated)
{
    real ul[NY];
    real vl[NY];
    real det[1];
    real nsat[1];
    real w[DC_MOTOR_LINK_KERN_CONTROL_SZ_W];
    int rc = DC_MOTOR_LINK_OK;
    if ((x == NULL) || (flags == NULL) || (gains == NULL) || (params == NULL) || (u == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else if (!dc_motor_link_finite(x, NX) || !dc_motor_link_finite(flags, DC_MOTOR_LINK_NFLAGS) ||
               !dc_motor_link_finite(gains, DC_MOTOR_LINK_NZ) ||
               !dc_motor_link_finite(params, DC_MOTOR_LINK_NP)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    } else {
        (void)dc_motor_link_kern_control(x, flags, gains, params, ul, vl, det, nsat, w);
        if (dc_motor_link_finite(det, 1) == 0) {
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        }
    }
    if (rc == DC_MOTOR_LINK_OK) {
        real mag = (det[0] < (real)0) ? -det[0] : det[0];
        if (!(mag >= ((DC_MOTOR_LINK_SINGULAR_RTOL) * (DC_MOTOR_LINK_DET_NOMINAL)))) {
            rc = DC_MOTOR_LINK_ERR_SINGULAR;
        } else if (!dc_motor_link_finite(ul, NY) || !dc_motor_link_finite(vl, NY)) {
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
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

int dc_motor_link_gains(const real lambda[NY], real gains[DC_MOTOR_LINK_NZ])
{
    static const int degree[NY] = DC_MOTOR_LINK_CHAIN_DEGREES;
    static const int offset[NY] = DC_MOTOR_LINK_CHAIN_OFFSETS;
    real out[DC_MOTOR_LINK_NZ] = {0};
    int j;
    int i;
    int rc = DC_MOTOR_LINK_OK;
    if ((lambda == NULL) || (gains == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else if (!dc_motor_link_finite(lambda, NY)) {
        rc = DC_MOTOR_LINK_ERR_NONFINITE;
    } else {
        for (j = 0; j < NY; j++) {
            if (!(lambda[j] > (real)0)) { /* poles at -lambda: 0 or below is not stable */
                rc = DC_MOTOR_LINK_ERR_ARG;
            }
        }
    }
    if (rc == DC_MOTOR_LINK_OK) {
        for (j = 0; j < NY; j++) {
            real binom = (real)1;
            real power = (real)1;
            for (i = 1; i <= degree[j]; i++) { /* k_i = C(r, i) lambda^i */
                binom = (binom * (((real)degree[j] - (real)i) + (real)1)) / (real)i;
                power = power * lambda[j];
                out[(offset[j] + i) - 1] = binom * power;
            }
        }
        if (dc_motor_link_finite(out, DC_MOTOR_LINK_NZ) != 0) {
            (void)memcpy(gains, out, sizeof(out));
        } else { /* lambda^r overflowed */
            rc = DC_MOTOR_LINK_ERR_NONFINITE;
        }
    }
    return rc;
}

int dc_motor_link_broadcast(const real u[DC_MOTOR_LINK_NU], const real v[NY], const real x[NX],
                            real w[DC_MOTOR_LINK_NW])
{
    int rc = DC_MOTOR_LINK_OK;
    if ((u == NULL) || (v == NULL) || (x == NULL) || (w == NULL)) {
        rc = DC_MOTOR_LINK_ERR_ARG;
    } else {
        (void)memcpy(w, u, sizeof(real) * (size_t)DC_MOTOR_LINK_NU);
    }
    return rc;
}
