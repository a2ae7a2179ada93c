/* DO NOT EDIT: unicycle module, generated from template control.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build unicycle`. */
/* Flatness-based control (docs/algorithms.md): v from the reference flags and the pole-placement
 * gains on each chain, u = G(x)^-1 (v - F(x)) with the model parameters as a runtime vector.
 * Near a singularity it refuses: |det G(x)| below SINGULAR_RTOL times its value at the model's
 * nominal state (DET_NOMINAL, in the header) gives ERR_SINGULAR and leaves u, v alone.
 * Declared input limits clamp u (and v = F + G u follows); *saturated counts clamped inputs. */
#include <string.h>
#include "unicycle_internal.h"

#define NX UNICYCLE_NX
#define NY UNICYCLE_NY

/* The model has no parameters: one unused entry (a C array has at least one). */
const real unicycle_params_default[UNICYCLE_NP_SLOTS] = {0.0};

/* The header's non-integer constants as objects, and the zeta index of each flat output
 * (internal). */
const real unicycle_ts = UNICYCLE_TS;
const uint8_t unicycle_chain_angle[NY] = UNICYCLE_CHAIN_ANGLE;
const uint8_t unicycle_heads[NY] = UNICYCLE_CHAIN_OFFSETS;

int unicycle_control(const real x[NX], const real flags[UNICYCLE_NFLAGS],
                     const real gains[UNICYCLE_NZ], const real params[UNICYCLE_NP_SLOTS],
                     real u[UNICYCLE_NU], real v[NY], uint32_t* saturated)
{
    real ul[NY];
    real vl[NY];
    real det[1];
    real nsat[1];
    real w[UNICYCLE_KERN_CONTROL_SZ_W];
    int rc = UNICYCLE_OK;
    if ((x == NULL) || (flags == NULL) || (gains == NULL) || (params == NULL) || (u == NULL)) {
        rc = UNICYCLE_ERR_ARG;
    } else if (!unicycle_finite(x, NX) || !unicycle_finite(flags, UNICYCLE_NFLAGS) ||
               !unicycle_finite(gains, UNICYCLE_NZ) || !unicycle_finite(params, UNICYCLE_NP)) {
        rc = UNICYCLE_ERR_NONFINITE;
    } else {
        (void)unicycle_kern_control(x, flags, gains, params, ul, vl, det, nsat, w);
        if (unicycle_finite(det, 1) == 0) {
            rc = UNICYCLE_ERR_SINGULAR;
        }
    }
    if (rc == UNICYCLE_OK) {
        real mag = (det[0] < (real)0) ? -det[0] : det[0];
        if (!(mag >= ((UNICYCLE_SINGULAR_RTOL) * (UNICYCLE_DET_NOMINAL)))) {
            rc = UNICYCLE_ERR_SINGULAR;
        } else if (!unicycle_finite(ul, NY) || !unicycle_finite(vl, NY)) {
            rc = UNICYCLE_ERR_NONFINITE;
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

int unicycle_gains(const real lambda[NY], real gains[UNICYCLE_NZ])
{
    static const int degree[NY] = UNICYCLE_CHAIN_DEGREES;
    static const int offset[NY] = UNICYCLE_CHAIN_OFFSETS;
    real out[UNICYCLE_NZ] = {0};
    int j;
    int i;
    int rc = UNICYCLE_OK;
    if ((lambda == NULL) || (gains == NULL)) {
        rc = UNICYCLE_ERR_ARG;
    } else if (!unicycle_finite(lambda, NY)) {
        rc = UNICYCLE_ERR_NONFINITE;
    } else {
        for (j = 0; j < NY; j++) {
            if (!(lambda[j] > (real)0)) { /* poles at -lambda: 0 or below is not stable */
                rc = UNICYCLE_ERR_ARG;
            }
        }
    }
    if (rc == UNICYCLE_OK) {
        for (j = 0; j < NY; j++) {
            real binom = (real)1;
            real power = (real)1;
            for (i = 1; i <= degree[j]; i++) { /* k_i = C(r, i) lambda^i */
                binom = (binom * (((real)degree[j] - (real)i) + (real)1)) / (real)i;
                power = power * lambda[j];
                out[(offset[j] + i) - 1] = binom * power;
            }
        }
        if (unicycle_finite(out, UNICYCLE_NZ) != 0) {
            (void)memcpy(gains, out, sizeof(out));
        } else { /* lambda^r overflowed */
            rc = UNICYCLE_ERR_NONFINITE;
        }
    }
    return rc;
}

int unicycle_broadcast(const real u[UNICYCLE_NU], const real v[NY], const real x[NX],
                       real w[UNICYCLE_NW])
{
    int rc = UNICYCLE_OK;
    if ((u == NULL) || (v == NULL) || (x == NULL) || (w == NULL)) {
        rc = UNICYCLE_ERR_ARG;
    } else {
        (void)memcpy(w, u, sizeof(real) * (size_t)UNICYCLE_NU);
    }
    return rc;
}

int unicycle_extension_step(real xi[UNICYCLE_NXI], const real u[UNICYCLE_NU],
                            real u_plant[UNICYCLE_NU])
{
    real next[UNICYCLE_NXI];
    real out[UNICYCLE_NU];
    int rc = UNICYCLE_OK;
    if ((xi == NULL) || (u == NULL) || (u_plant == NULL)) {
        rc = UNICYCLE_ERR_ARG;
    } else if (!unicycle_finite(xi, UNICYCLE_NXI) || !unicycle_finite(u, UNICYCLE_NU)) {
        rc = UNICYCLE_ERR_NONFINITE;
    } else {
        out[0] = xi[0]; /* v */
        next[0] = (xi[0] * 1.0) + (u[0] * 0.02); /* v */
        out[1] = u[1]; /* w: no integrator */
        if (!unicycle_finite(next, UNICYCLE_NXI)) {
            rc = UNICYCLE_ERR_NONFINITE;
        } else {
            (void)memcpy(xi, next, sizeof(next));
            (void)memcpy(u_plant, out, sizeof(out));
        }
    }
    return rc;
}
