/* DO NOT EDIT: dc_motor_link module, generated from template kernels.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* Flatness-based controller kernel: u and v = F + G u from the estimate, flags and gains:
 * control.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only); a
 * kernel that is another on packed copies of its matrices is that call between two copy loops. */
#include <math.h>
#include "dc_motor_link_internal.h"

static dc_motor_link_real dc_motor_link_control_sq(dc_motor_link_real x)
{
    return x * x;
}

/* dc_motor_link_kern_control:(x[3],flags[4],gains[3],params[8])->(u,v,det,nsat) */
int dc_motor_link_kern_control(const dc_motor_link_real x[3], const dc_motor_link_real flags[4],
                               const dc_motor_link_real gains[3],
                               const dc_motor_link_real params[8], dc_motor_link_real u[1],
                               dc_motor_link_real v[1], dc_motor_link_real det[1],
                               dc_motor_link_real nsat[1], dc_motor_link_real w[13])
{
    w[0] = flags[3];
    w[1] = gains[2];
    w[2] = x[0];
    w[3] = flags[0];
    w[3] = (w[2] - w[3]);
    w[4] = 6.2831853071795862e+00;
    w[3] = fmod(w[3], w[4]);
    w[5] = 3.1415926535897931e+00;
    w[5] = (w[5] < w[3]);
    w[5] = (w[4] * w[5]);
    w[5] = (w[3] - w[5]);
    w[6] = -3.1415926535897931e+00;
    w[3] = (w[3] <= w[6]);
    w[4] = (w[4] * w[3]);
    w[5] = (w[5] + w[4]);
    w[1] = (w[1] * w[5]);
    w[0] = (w[0] - w[1]);
    w[1] = gains[1];
    w[5] = x[1];
    w[4] = flags[1];
    w[4] = (w[5] - w[4]);
    w[1] = (w[1] * w[4]);
    w[0] = (w[0] - w[1]);
    w[1] = gains[0];
    w[4] = x[2];
    w[3] = flags[2];
    w[3] = (w[4] - w[3]);
    w[1] = (w[1] * w[3]);
    w[0] = (w[0] - w[1]);
    w[1] = params[4];
    w[3] = (1. / w[1]);
    w[6] = params[0];
    w[3] = (w[3] / w[6]);
    w[7] = params[2];
    w[8] = dc_motor_link_control_sq(w[7]);
    w[8] = (w[5] * w[8]);
    w[9] = params[1];
    w[10] = (w[1] * w[9]);
    w[10] = (w[10] * w[4]);
    w[8] = (w[8] + w[10]);
    w[10] = params[3];
    w[11] = (w[6] * w[10]);
    w[11] = (w[11] * w[4]);
    w[8] = (w[8] + w[11]);
    w[10] = (w[9] * w[10]);
    w[10] = (w[10] * w[5]);
    w[8] = (w[8] + w[10]);
    w[10] = params[6];
    w[9] = (w[9] * w[10]);
    w[11] = params[7];
    w[9] = (w[9] * w[11]);
    w[4] = params[5];
    w[9] = (w[9] * w[4]);
    w[12] = sin(w[2]);
    w[9] = (w[9] * w[12]);
    w[8] = (w[8] + w[9]);
    w[10] = (w[6] * w[10]);
    w[10] = (w[10] * w[11]);
    w[10] = (w[10] * w[4]);
    w[10] = (w[10] * w[5]);
    w[2] = cos(w[2]);
    w[10] = (w[10] * w[2]);
    w[8] = (w[8] + w[10]);
    w[3] = (w[3] * w[8]);
    w[3] = (w[0] + w[3]);
    w[7] = (w[7] / w[1]);
    w[7] = (w[7] / w[6]);
    w[3] = (w[3] / w[7]);
    u[0] = w[3];
    v[0] = w[0];
    det[0] = w[7];
    w[7] = 0.;
    nsat[0] = w[7];
    return 0;
    return 0;
}
