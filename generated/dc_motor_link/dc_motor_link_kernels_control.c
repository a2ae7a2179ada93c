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
                               dc_motor_link_real nsat[1], dc_motor_link_real w[27])
{
    w[0] = 1.0000000000000000e-02;
    w[1] = flags[3];
    w[2] = gains[2];
    w[3] = x[0];
    w[4] = flags[0];
    w[4] = (w[3] - w[4]);
    w[5] = 6.2831853071795862e+00;
    w[4] = fmod(w[4], w[5]);
    w[6] = 3.1415926535897931e+00;
    w[6] = (w[6] < w[4]);
    w[6] = (w[5] * w[6]);
    w[6] = (w[4] - w[6]);
    w[7] = -3.1415926535897931e+00;
    w[4] = (w[4] <= w[7]);
    w[5] = (w[5] * w[4]);
    w[6] = (w[6] + w[5]);
    w[2] = (w[2] * w[6]);
    w[1] = (w[1] - w[2]);
    w[2] = gains[1];
    w[6] = x[1];
    w[5] = flags[1];
    w[5] = (w[6] - w[5]);
    w[2] = (w[2] * w[5]);
    w[1] = (w[1] - w[2]);
    w[2] = gains[0];
    w[5] = x[2];
    w[4] = flags[2];
    w[4] = (w[5] - w[4]);
    w[2] = (w[2] * w[4]);
    w[1] = (w[1] - w[2]);
    w[0] = (w[0] * w[1]);
    w[2] = -2.7058189522038817e-01;
    w[2] = (w[2] * w[6]);
    w[4] = -6.6162097097546821e-02;
    w[4] = (w[4] * w[5]);
    w[2] = (w[2] + w[4]);
    w[4] = (w[0] - w[2]);
    w[7] = 2.3246418812889998e-03;
    w[8] = params[4];
    w[9] = (1. / w[8]);
    w[10] = params[0];
    w[9] = (w[9] / w[10]);
    w[11] = params[2];
    w[12] = dc_motor_link_control_sq(w[11]);
    w[13] = (w[6] * w[12]);
    w[14] = params[1];
    w[15] = (w[8] * w[14]);
    w[16] = (w[15] * w[5]);
    w[13] = (w[13] + w[16]);
    w[16] = params[3];
    w[17] = (w[10] * w[16]);
    w[18] = (w[17] * w[5]);
    w[13] = (w[13] + w[18]);
    w[16] = (w[14] * w[16]);
    w[18] = (w[16] * w[6]);
    w[13] = (w[13] + w[18]);
    w[18] = params[6];
    w[14] = (w[14] * w[18]);
    w[19] = params[7];
    w[14] = (w[14] * w[19]);
    w[20] = params[5];
    w[14] = (w[14] * w[20]);
    w[21] = sin(w[3]);
    w[22] = (w[14] * w[21]);
    w[13] = (w[13] + w[22]);
    w[18] = (w[10] * w[18]);
    w[18] = (w[18] * w[19]);
    w[18] = (w[18] * w[20]);
    w[20] = (w[18] * w[6]);
    w[3] = cos(w[3]);
    w[20] = (w[20] * w[3]);
    w[13] = (w[13] + w[20]);
    w[13] = (w[9] * w[13]);
    w[20] = (w[7] * w[13]);
    w[4] = (w[4] + w[20]);
    w[11] = (w[11] / w[8]);
    w[11] = (w[11] / w[10]);
    w[10] = (w[7] * w[11]);
    w[4] = (w[4] / w[10]);
    w[8] = (w[11] * w[4]);
    w[13] = (w[8] - w[13]);
    w[7] = (w[7] * w[13]);
    w[2] = (w[2] + w[7]);
    w[7] = 1.8388168210696336e-03;
    w[20] = -1.1270536220551969e-03;
    w[20] = (w[20] * w[6]);
    w[19] = 9.7258795860950993e-03;
    w[19] = (w[19] * w[5]);
    w[20] = (w[20] + w[19]);
    w[19] = 1.8388168210697328e-05;
    w[19] = (w[19] * w[13]);
    w[20] = (w[20] + w[19]);
    w[19] = (w[6] + w[20]);
    w[12] = (w[19] * w[12]);
    w[22] = (w[5] + w[2]);
    w[15] = (w[15] * w[22]);
    w[12] = (w[12] + w[15]);
    w[17] = (w[17] * w[22]);
    w[12] = (w[12] + w[17]);
    w[16] = (w[16] * w[19]);
    w[12] = (w[12] + w[16]);
    w[16] = 1.;
    w[17] = 9.9967697772129962e-03;
    w[17] = (w[17] * w[6]);
    w[6] = 4.9216512273029617e-05;
    w[6] = (w[6] * w[5]);
    w[17] = (w[17] + w[6]);
    w[6] = 7.6592159161073515e-08;
    w[6] = (w[6] * w[13]);
    w[17] = (w[17] + w[6]);
    w[6] = dc_motor_link_control_sq(w[17]);
    w[5] = -5.0000000000000000e-01;
    w[22] = 4.1666666666666664e-02;
    w[15] = -1.3888888888888889e-03;
    w[23] = 2.4801587301587302e-05;
    w[24] = -2.7557319223985888e-07;
    w[25] = 2.0876756987868100e-09;
    w[25] = (w[25] * w[6]);
    w[24] = (w[24] + w[25]);
    w[24] = (w[6] * w[24]);
    w[23] = (w[23] + w[24]);
    w[23] = (w[6] * w[23]);
    w[15] = (w[15] + w[23]);
    w[15] = (w[6] * w[15]);
    w[22] = (w[22] + w[15]);
    w[22] = (w[6] * w[22]);
    w[5] = (w[5] + w[22]);
    w[5] = (w[6] * w[5]);
    w[5] = (w[16] + w[5]);
    w[22] = (w[21] * w[5]);
    w[15] = -1.6666666666666666e-01;
    w[23] = 8.3333333333333332e-03;
    w[24] = -1.9841269841269841e-04;
    w[25] = 2.7557319223985893e-06;
    w[26] = -2.5052108385441720e-08;
    w[26] = (w[26] * w[6]);
    w[25] = (w[25] + w[26]);
    w[25] = (w[6] * w[25]);
    w[24] = (w[24] + w[25]);
    w[24] = (w[6] * w[24]);
    w[23] = (w[23] + w[24]);
    w[23] = (w[6] * w[23]);
    w[15] = (w[15] + w[23]);
    w[6] = (w[6] * w[15]);
    w[16] = (w[16] + w[6]);
    w[16] = (w[16] * w[17]);
    w[6] = (w[3] * w[16]);
    w[22] = (w[22] + w[6]);
    w[14] = (w[14] * w[22]);
    w[12] = (w[12] + w[14]);
    w[18] = (w[18] * w[19]);
    w[3] = (w[3] * w[5]);
    w[21] = (w[21] * w[16]);
    w[3] = (w[3] - w[21]);
    w[18] = (w[18] * w[3]);
    w[12] = (w[12] + w[18]);
    w[9] = (w[9] * w[12]);
    w[8] = (w[8] - w[9]);
    w[8] = (w[8] - w[13]);
    w[13] = -14715.;
    w[13] = (w[13] * w[17]);
    w[17] = -3.5367874999999999e+03;
    w[17] = (w[17] * w[20]);
    w[13] = (w[13] + w[17]);
    w[17] = -4.0250000000000000e+02;
    w[17] = (w[17] * w[2]);
    w[13] = (w[13] + w[17]);
    w[8] = (w[8] - w[13]);
    w[7] = (w[7] * w[8]);
    w[2] = (w[2] + w[7]);
    w[0] = (w[0] - w[2]);
    w[0] = (w[0] / w[10]);
    w[4] = (w[4] + w[0]);
    u[0] = w[4];
    v[0] = w[1];
    det[0] = w[11];
    w[11] = 0.;
    nsat[0] = w[11];
    return 0;
    return 0;
}
