/* DO NOT EDIT: pvtol module, generated from template control.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/* Flatness-based control (docs/algorithms.md): v from the reference flags and the pole-placement
 * gains on each chain, u = G(x)^-1 (v - F(x)) with the model parameters as a runtime vector.
 * Near a singularity it refuses: |det G(x)| below SINGULAR_RTOL times its value at the model's
 * nominal state (DET_NOMINAL, in the header) gives ERR_SINGULAR and leaves u, v alone.
 * Declared input limits clamp u (and v = F + G u follows); *saturated counts clamped inputs. */
#include <string.h>
#include "pvtol_internal.h"

#define NX PVTOL_NX
#define NY PVTOL_NY

/* Nominal parameter values, in model order: m, J, g. */
const real pvtol_params_default[PVTOL_NP_SLOTS] = {
    [PVTOL_P_m] = 0.7, /* [kg] */
    [PVTOL_P_J] = 0.005, /* [kg*m^2] */
    [PVTOL_P_g] = 9.81 /* [m/s^2] */
};

/* The header's non-integer constants as objects, and the zeta index of each flat output
 * (internal). */
const real pvtol_ts = PVTOL_TS;
const uint8_t pvtol_chain_angle[NY] = PVTOL_CHAIN_ANGLE;
const uint8_t pvtol_heads[NY] = PVTOL_CHAIN_OFFSETS;

int pvtol_control(const real x[NX], const real flags[PVTOL_NFLAGS], const real gains[PVTOL_NZ],
                  const real params[PVTOL_NP_SLOTS], real u[PVTOL_NU], real v[NY],
                  uint32_t* saturated)
{
    real ul[NY];
    real vl[NY];
    real det[1];
    real nsat[1];
    real w[PVTOL_KERN_CONTROL_SZ_W];
    int rc = PVTOL_OK;
    if ((x == NULL) || (flags == NULL) || (gains == NULL) || (params == NULL) || (u == NULL)) {
        rc = PVTOL_ERR_ARG;
    } else if (!pvtol_finite(x, NX) || !pvtol_finite(flags, PVTOL_NFLAGS) ||
               !pvtol_finite(gains, PVTOL_NZ) || !pvtol_finite(params, PVTOL_NP)) {
        rc = PVTOL_ERR_NONFINITE;
    } else {
        (void)pvtol_kern_control(x, flags, gains, params, ul, vl, det, nsat, w);
        if (pvtol_finite(det, 1) == 0) {
            rc = PVTOL_ERR_SINGULAR;
        }
    }
    if (rc == PVTOL_OK) {
        real mag = (det[0] < (real)0) ? -det[0] : det[0];
        if (!(mag >= ((PVTOL_SINGULAR_RTOL) * (PVTOL_DET_NOMINAL)))) {
            rc = PVTOL_ERR_SINGULAR;
        } else if (!pvtol_finite(ul, NY) || !pvtol_finite(vl, NY)) {
            rc = PVTOL_ERR_NONFINITE;
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

int pvtol_gains(const real lambda[NY], real gains[PVTOL_NZ])
{
    static const int degree[NY] = PVTOL_CHAIN_DEGREES;
    static const int offset[NY] = PVTOL_CHAIN_OFFSETS;
    real out[PVTOL_NZ] = {0};
    int j;
    int i;
    int rc = PVTOL_OK;
    if ((lambda == NULL) || (gains == NULL)) {
        rc = PVTOL_ERR_ARG;
    } else if (!pvtol_finite(lambda, NY)) {
        rc = PVTOL_ERR_NONFINITE;
    } else {
        for (j = 0; j < NY; j++) {
            if (!(lambda[j] > (real)0)) { /* poles at -lambda: 0 or below is not stable */
                rc = PVTOL_ERR_ARG;
            }
        }
    }
    if (rc == PVTOL_OK) {
        for (j = 0; j < NY; j++) {
            real binom = (real)1;
            real power = (real)1;
            for (i = 1; i <= degree[j]; i++) { /* k_i = C(r, i) lambda^i */
                binom = (binom * (((real)degree[j] - (real)i) + (real)1)) / (real)i;
                power = power * lambda[j];
                out[(offset[j] + i) - 1] = binom * power;
            }
        }
        if (pvtol_finite(out, PVTOL_NZ) != 0) {
            (void)memcpy(gains, out, sizeof(out));
        } else { /* lambda^r overflowed */
            rc = PVTOL_ERR_NONFINITE;
        }
    }
    return rc;
}

int pvtol_broadcast(const real u[PVTOL_NU], const real v[NY], const real x[NX], real w[PVTOL_NW])
{
    int rc = PVTOL_OK;
    if ((u == NULL) || (v == NULL) || (x == NULL) || (w == NULL)) {
        rc = PVTOL_ERR_ARG;
    } else {
        (void)memcpy(w, u, sizeof(real) * (size_t)PVTOL_NU);
    }
    return rc;
}

int pvtol_extension_step(real xi[PVTOL_NXI], const real u[PVTOL_NU], real u_plant[PVTOL_NU])
{
    real next[PVTOL_NXI];
    real out[PVTOL_NU];
    int rc = PVTOL_OK;
    if ((xi == NULL) || (u == NULL) || (u_plant == NULL)) {
        rc = PVTOL_ERR_ARG;
    } else if (!pvtol_finite(xi, PVTOL_NXI) || !pvtol_finite(u, PVTOL_NU)) {
        rc = PVTOL_ERR_NONFINITE;
    } else {
        out[0] = xi[0]; /* T */
        next[0] = (xi[0] * 1.0) + (xi[1] * 0.01) + (u[0] * 5e-05); /* T */
        next[1] = (xi[1] * 1.0) + (u[0] * 0.01); /* T_d1 */
        out[1] = u[1]; /* tau: no integrator */
        if (!pvtol_finite(next, PVTOL_NXI)) {
            rc = PVTOL_ERR_NONFINITE;
        } else {
            (void)memcpy(xi, next, sizeof(next));
            (void)memcpy(u_plant, out, sizeof(out));
        }
    }
    return rc;
}
