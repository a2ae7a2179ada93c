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
                          unicycle_real nsat[1], unicycle_real w[12])
{
    (void)params;
    w[0] = x[1];
    w[1] = x[3];
    w[2] = unicycle_control_hypot(w[0], w[1]);
    w[3] = (w[0] / w[2]);
    w[4] = (w[3] * w[0]);
    w[2] = (w[1] / w[2]);
    w[5] = (w[1] * w[2]);
    w[4] = (w[4] + w[5]);
    w[5] = (w[0] / w[4]);
    w[6] = flags[2];
    w[7] = gains[1];
    w[8] = x[0];
    w[9] = flags[0];
    w[8] = (w[8] - w[9]);
    w[7] = (w[7] * w[8]);
    w[6] = (w[6] - w[7]);
    w[7] = gains[0];
    w[8] = flags[1];
    w[8] = (w[0] - w[8]);
    w[7] = (w[7] * w[8]);
    w[6] = (w[6] - w[7]);
    w[5] = (w[5] * w[6]);
    w[7] = (w[1] / w[4]);
    w[8] = flags[5];
    w[9] = gains[3];
    w[10] = x[2];
    w[11] = flags[3];
    w[10] = (w[10] - w[11]);
    w[9] = (w[9] * w[10]);
    w[8] = (w[8] - w[9]);
    w[9] = gains[2];
    w[10] = flags[4];
    w[10] = (w[1] - w[10]);
    w[9] = (w[9] * w[10]);
    w[8] = (w[8] - w[9]);
    w[7] = (w[7] * w[8]);
    w[5] = (w[5] + w[7]);
    u[0] = w[5];
    w[7] = (w[3] / w[4]);
    w[7] = (w[7] * w[8]);
    w[8] = (w[2] / w[4]);
    w[8] = (w[8] * w[6]);
    w[7] = (w[7] - w[8]);
    w[8] = -4.;
    w[6] = unicycle_control_fmax(w[7], w[8]);
    w[9] = 4.;
    w[6] = unicycle_control_fmin(w[6], w[9]);
    u[1] = w[6];
    w[3] = (w[3] * w[5]);
    w[1] = (w[1] * w[6]);
    w[3] = (w[3] - w[1]);
    v[0] = w[3];
    w[2] = (w[2] * w[5]);
    w[0] = (w[0] * w[6]);
    w[2] = (w[2] + w[0]);
    v[1] = w[2];
    det[0] = w[4];
    w[8] = (w[7] < w[8]);
    w[9] = (w[9] < w[7]);
    w[8] = (w[8] + w[9]);
    nsat[0] = w[8];
    return 0;
    return 0;
}
