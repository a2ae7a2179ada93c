/* DO NOT EDIT: pvtol module, generated from template kernels.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/* Flatness-based controller kernel: u and v = F + G u from the estimate, flags and gains:
 * control.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only); a
 * kernel that is another on packed copies of its matrices is that call between two copy loops. */
#include <math.h>
#include "pvtol_internal.h"

static pvtol_real pvtol_control_hypot(pvtol_real x, pvtol_real y)
{
    return hypot(x, y);
}

static pvtol_real pvtol_control_sq(pvtol_real x)
{
    return x * x;
}

static pvtol_real pvtol_control_fmax(pvtol_real x, pvtol_real y)
{
    return fmax(x, y);
}

static pvtol_real pvtol_control_fmin(pvtol_real x, pvtol_real y)
{
    return fmin(x, y);
}

/* pvtol_kern_control:(x[8],flags[10],gains[8],params[3])->(u[2],v[2],det,nsat) */
int pvtol_kern_control(const pvtol_real x[8], const pvtol_real flags[10], const pvtol_real gains[8],
                       const pvtol_real params[3], pvtol_real u[2], pvtol_real v[2],
                       pvtol_real det[1], pvtol_real nsat[1], pvtol_real w[18])
{
    w[0] = x[2];
    w[1] = params[1];
    w[2] = (w[0] / w[1]);
    w[3] = params[0];
    w[4] = (w[0] / w[3]);
    w[5] = params[2];
    w[6] = x[6];
    w[7] = (w[5] + w[6]);
    w[8] = pvtol_control_hypot(w[0], w[7]);
    w[4] = (w[4] / w[8]);
    w[9] = (w[4] * w[2]);
    w[1] = (w[7] / w[1]);
    w[10] = (1. / w[3]);
    w[10] = (w[10] / w[8]);
    w[10] = (w[10] * w[7]);
    w[8] = (w[1] * w[10]);
    w[9] = (w[9] + w[8]);
    w[8] = (w[2] / w[9]);
    w[11] = flags[4];
    w[12] = gains[3];
    w[13] = x[0];
    w[14] = flags[0];
    w[13] = (w[13] - w[14]);
    w[12] = (w[12] * w[13]);
    w[11] = (w[11] - w[12]);
    w[12] = gains[2];
    w[13] = x[1];
    w[14] = flags[1];
    w[13] = (w[13] - w[14]);
    w[12] = (w[12] * w[13]);
    w[11] = (w[11] - w[12]);
    w[12] = gains[1];
    w[13] = flags[2];
    w[13] = (w[0] - w[13]);
    w[12] = (w[12] * w[13]);
    w[11] = (w[11] - w[12]);
    w[12] = gains[0];
    w[13] = x[3];
    w[14] = flags[3];
    w[14] = (w[13] - w[14]);
    w[12] = (w[12] * w[14]);
    w[11] = (w[11] - w[12]);
    w[12] = x[7];
    w[14] = (w[0] * w[12]);
    w[15] = pvtol_control_sq(w[5]);
    w[16] = pvtol_control_sq(w[0]);
    w[15] = (w[15] + w[16]);
    w[16] = pvtol_control_sq(w[6]);
    w[15] = (w[15] + w[16]);
    w[16] = (2. * w[5]);
    w[16] = (w[16] * w[6]);
    w[15] = (w[15] + w[16]);
    w[14] = (w[14] / w[15]);
    w[16] = (w[5] * w[13]);
    w[16] = (w[16] / w[15]);
    w[14] = (w[14] - w[16]);
    w[16] = (w[13] * w[6]);
    w[16] = (w[16] / w[15]);
    w[14] = (w[14] - w[16]);
    w[16] = (w[0] * w[14]);
    w[5] = (w[5] * w[3]);
    w[5] = (w[5] * w[12]);
    w[15] = sqrt(w[15]);
    w[5] = (w[5] / w[15]);
    w[0] = (w[3] * w[0]);
    w[0] = (w[0] * w[13]);
    w[0] = (w[0] / w[15]);
    w[5] = (w[5] + w[0]);
    w[3] = (w[3] * w[6]);
    w[3] = (w[3] * w[12]);
    w[3] = (w[3] / w[15]);
    w[5] = (w[5] + w[3]);
    w[3] = (w[10] * w[5]);
    w[16] = (w[16] + w[3]);
    w[16] = (w[16] * w[14]);
    w[3] = (w[10] * w[14]);
    w[3] = (w[3] * w[5]);
    w[16] = (w[16] + w[3]);
    w[11] = (w[11] + w[16]);
    w[8] = (w[8] * w[11]);
    w[3] = (w[1] / w[9]);
    w[15] = flags[9];
    w[0] = gains[7];
    w[13] = x[4];
    w[17] = flags[5];
    w[13] = (w[13] - w[17]);
    w[0] = (w[0] * w[13]);
    w[15] = (w[15] - w[0]);
    w[0] = gains[6];
    w[13] = x[5];
    w[17] = flags[6];
    w[13] = (w[13] - w[17]);
    w[0] = (w[0] * w[13]);
    w[15] = (w[15] - w[0]);
    w[0] = gains[5];
    w[13] = flags[7];
    w[6] = (w[6] - w[13]);
    w[0] = (w[0] * w[6]);
    w[15] = (w[15] - w[0]);
    w[0] = gains[4];
    w[6] = flags[8];
    w[12] = (w[12] - w[6]);
    w[0] = (w[0] * w[12]);
    w[15] = (w[15] - w[0]);
    w[0] = (w[4] * w[5]);
    w[7] = (w[7] * w[14]);
    w[0] = (w[0] - w[7]);
    w[0] = (w[0] * w[14]);
    w[14] = (w[4] * w[14]);
    w[14] = (w[14] * w[5]);
    w[0] = (w[0] + w[14]);
    w[15] = (w[15] - w[0]);
    w[3] = (w[3] * w[15]);
    w[8] = (w[8] + w[3]);
    u[0] = w[8];
    w[3] = (w[4] / w[9]);
    w[3] = (w[3] * w[15]);
    w[15] = (w[10] / w[9]);
    w[15] = (w[15] * w[11]);
    w[3] = (w[3] - w[15]);
    w[15] = -1.;
    w[11] = pvtol_control_fmax(w[3], w[15]);
    w[14] = 1.;
    w[11] = pvtol_control_fmin(w[11], w[14]);
    u[1] = w[11];
    w[4] = (w[4] * w[8]);
    w[1] = (w[1] * w[11]);
    w[4] = (w[4] - w[1]);
    w[4] = (w[4] - w[16]);
    v[0] = w[4];
    w[10] = (w[10] * w[8]);
    w[2] = (w[2] * w[11]);
    w[10] = (w[10] + w[2]);
    w[0] = (w[0] + w[10]);
    v[1] = w[0];
    det[0] = w[9];
    w[15] = (w[3] < w[15]);
    w[14] = (w[14] < w[3]);
    w[15] = (w[15] + w[14]);
    nsat[0] = w[15];
    return 0;
    return 0;
}
