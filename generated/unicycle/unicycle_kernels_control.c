/* DO NOT EDIT: unicycle module, generated from template kernels.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build unicycle`. */
/* Flatness-based controller kernel: u and v = F + G u from the estimate, flags and gains:
 * control.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only); a
 * kernel that is another on packed copies of its matrices is that call between two copy loops. */
#include <math.h>
#include "unicycle_internal.h"

static unicycle_real unicycle_control_hypot(unicycle_real x, unicycle_real y)
{
    return hypot(x, y);
}

static unicycle_real unicycle_control_fmax(unicycle_real x, unicycle_real y)
{
    return fmax(x, y);
}

static unicycle_real unicycle_control_fmin(unicycle_real x, unicycle_real y)
{
    return fmin(x, y);
}

/* unicycle_kern_control:(x[4],flags[6],gains[4],params[0])->(u[2],v[2],det,nsat) */
int unicycle_kern_control(const unicycle_real x[4], const unicycle_real flags[6],
                          const unicycle_real gains[4], const unicycle_real params[1],
                          unicycle_real u[2], unicycle_real v[2], unicycle_real det[1],
                          unicycle_real nsat[1], unicycle_real w[24])
{
    (void)params;
    w[0] = 2.0000000000000000e-02;
    w[1] = x[1];
    w[2] = (w[0] * w[1]);
    w[3] = x[3];
    w[4] = unicycle_control_hypot(w[1], w[3]);
    w[5] = (w[1] / w[4]);
    w[6] = (w[0] * w[5]);
    w[7] = (w[6] * w[2]);
    w[8] = (w[0] * w[3]);
    w[4] = (w[3] / w[4]);
    w[9] = (w[0] * w[4]);
    w[10] = (w[8] * w[9]);
    w[7] = (w[7] + w[10]);
    w[2] = (w[2] / w[7]);
    w[10] = flags[2];
    w[11] = gains[1];
    w[12] = x[0];
    w[13] = flags[0];
    w[12] = (w[12] - w[13]);
    w[11] = (w[11] * w[12]);
    w[10] = (w[10] - w[11]);
    w[11] = gains[0];
    w[12] = flags[1];
    w[12] = (w[1] - w[12]);
    w[11] = (w[11] * w[12]);
    w[10] = (w[10] - w[11]);
    w[10] = (w[0] * w[10]);
    w[11] = (w[2] * w[10]);
    w[8] = (w[8] / w[7]);
    w[12] = flags[5];
    w[13] = gains[3];
    w[14] = x[2];
    w[15] = flags[3];
    w[14] = (w[14] - w[15]);
    w[13] = (w[13] * w[14]);
    w[12] = (w[12] - w[13]);
    w[13] = gains[2];
    w[14] = flags[4];
    w[14] = (w[3] - w[14]);
    w[13] = (w[13] * w[14]);
    w[12] = (w[12] - w[13]);
    w[12] = (w[0] * w[12]);
    w[13] = (w[8] * w[12]);
    w[11] = (w[11] + w[13]);
    w[13] = (w[5] * w[11]);
    w[6] = (w[6] / w[7]);
    w[14] = (w[6] * w[12]);
    w[9] = (w[9] / w[7]);
    w[7] = (w[9] * w[10]);
    w[14] = (w[14] - w[7]);
    w[7] = -4.;
    w[14] = unicycle_control_fmax(w[14], w[7]);
    w[15] = 4.;
    w[14] = unicycle_control_fmin(w[14], w[15]);
    w[16] = (w[3] * w[14]);
    w[13] = (w[13] - w[16]);
    w[16] = (w[0] * w[13]);
    w[17] = 1.0000000000000000e-02;
    w[18] = (w[1] + w[16]);
    w[19] = (w[4] * w[11]);
    w[20] = (w[1] * w[14]);
    w[19] = (w[19] + w[20]);
    w[0] = (w[0] * w[19]);
    w[20] = (w[3] + w[0]);
    w[21] = unicycle_control_hypot(w[18], w[20]);
    w[22] = (w[18] / w[21]);
    w[22] = (w[22] * w[11]);
    w[23] = (w[20] * w[14]);
    w[22] = (w[22] - w[23]);
    w[22] = (w[22] - w[13]);
    w[22] = (w[17] * w[22]);
    w[16] = (w[16] + w[22]);
    w[10] = (w[10] - w[16]);
    w[2] = (w[2] * w[10]);
    w[20] = (w[20] / w[21]);
    w[20] = (w[20] * w[11]);
    w[18] = (w[18] * w[14]);
    w[20] = (w[20] + w[18]);
    w[20] = (w[20] - w[19]);
    w[17] = (w[17] * w[20]);
    w[0] = (w[0] + w[17]);
    w[12] = (w[12] - w[0]);
    w[8] = (w[8] * w[12]);
    w[2] = (w[2] + w[8]);
    w[11] = (w[11] + w[2]);
    u[0] = w[11];
    w[6] = (w[6] * w[12]);
    w[9] = (w[9] * w[10]);
    w[6] = (w[6] - w[9]);
    w[14] = (w[14] + w[6]);
    w[6] = unicycle_control_fmax(w[14], w[7]);
    w[6] = unicycle_control_fmin(w[6], w[15]);
    u[1] = w[6];
    w[9] = (w[5] * w[11]);
    w[10] = (w[3] * w[6]);
    w[9] = (w[9] - w[10]);
    v[0] = w[9];
    w[11] = (w[4] * w[11]);
    w[6] = (w[1] * w[6]);
    w[11] = (w[11] + w[6]);
    v[1] = w[11];
    w[5] = (w[5] * w[1]);
    w[3] = (w[3] * w[4]);
    w[5] = (w[5] + w[3]);
    det[0] = w[5];
    w[7] = (w[14] < w[7]);
    w[15] = (w[15] < w[14]);
    w[7] = (w[7] + w[15]);
    nsat[0] = w[7];
    return 0;
    return 0;
}
