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
const real dc_motor_link_params_default[DC_MOTOR_LINK_NP] = {
    0.005, /* L [H] */
    2.0, /* R [ohm] */
    0.5, /* k_e [N*m/A] */
    0.05, /* k_d [N*m*s/rad] */
    0.02, /* J [kg*m^2] */
    0.3, /* m [kg] */
    9.81, /* g [m/s^2] */
    0.25 /* l [m] */
};

int dc_motor_link_control(const real x[NX], const real flags[DC_MOTOR_LINK_NFLAGS],
                          const real gains[NX], const real params[DC_MOTOR_LINK_NP],
                          real u[DC_MOTOR_LINK_NU], real v[NY], uint32_t* saturated)
{
    real ul[NY], vl[NY], det[1], nsat[1], mag;
    real w[DC_MOTOR_LINK_KERN_CONTROL_SZ_W];
    if (!x || !flags || !gains || !params || !u) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (!dc_motor_link_finite(x, NX) || !dc_motor_link_finite(flags, DC_MOTOR_LINK_NFLAGS) ||
        !dc_motor_link_finite(gains, NX) || !dc_motor_link_finite(params, DC_MOTOR_LINK_NP)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    (void)dc_motor_link_kern_control(x, flags, gains, params, ul, vl, det, nsat, w);
    if (!dc_motor_link_finite(det, 1)) {
        return DC_MOTOR_LINK_ERR_SINGULAR;
    }
    mag = (det[0] < (real)0) ? -det[0] : det[0];
    if (!(mag >= ((DC_MOTOR_LINK_SINGULAR_RTOL) * (DC_MOTOR_LINK_DET_NOMINAL)))) {
        return DC_MOTOR_LINK_ERR_SINGULAR;
    }
    if (!dc_motor_link_finite(ul, NY) || !dc_motor_link_finite(vl, NY)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    (void)memcpy(u, ul, sizeof(ul));
    if (v != NULL) {
        (void)memcpy(v, vl, sizeof(vl));
    }
    if (saturated != NULL) {
        *saturated += (uint32_t)nsat[0];
    }
    return DC_MOTOR_LINK_OK;
}

int dc_motor_link_gains(const real lambda[NY], real gains[NX])
{
    static const int degree[NY] = DC_MOTOR_LINK_CHAIN_DEGREES;
    static const int offset[NY] = DC_MOTOR_LINK_CHAIN_OFFSETS;
    real out[NX];
    int j, i;
    if (!lambda || !gains) {
        return DC_MOTOR_LINK_ERR_ARG;
    }
    if (!dc_motor_link_finite(lambda, NY)) {
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    for (j = 0; j < NY; j++) {
        real binom = (real)1, power = (real)1;
        for (i = 1; i <= degree[j]; i++) { /* k_i = C(r, i) lambda^i */
            binom = binom * ((real)degree[j] - (real)i + (real)1) / (real)i;
            power = power * lambda[j];
            out[offset[j] + i - 1] = binom * power;
        }
    }
    if (!dc_motor_link_finite(out, NX)) { /* lambda^r overflowed */
        return DC_MOTOR_LINK_ERR_NONFINITE;
    }
    (void)memcpy(gains, out, sizeof(out));
    return DC_MOTOR_LINK_OK;
}
