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
                       pvtol_real det[1], pvtol_real nsat[1], pvtol_real w[38])
{
    w[0] = 1.0000000000000000e-02;
    w[1] = x[2];
    w[2] = params[1];
    w[3] = (w[1] / w[2]);
    w[4] = (w[0] * w[3]);
    w[5] = params[0];
    w[6] = (w[1] / w[5]);
    w[7] = params[2];
    w[8] = x[6];
    w[9] = (w[7] + w[8]);
    w[10] = pvtol_control_hypot(w[1], w[9]);
    w[6] = (w[6] / w[10]);
    w[11] = (w[0] * w[6]);
    w[12] = (w[11] * w[4]);
    w[13] = (w[9] / w[2]);
    w[14] = (w[0] * w[13]);
    w[15] = (1. / w[5]);
    w[10] = (w[15] / w[10]);
    w[10] = (w[10] * w[9]);
    w[16] = (w[0] * w[10]);
    w[17] = (w[14] * w[16]);
    w[12] = (w[12] + w[17]);
    w[4] = (w[4] / w[12]);
    w[17] = flags[4];
    w[18] = gains[3];
    w[19] = x[0];
    w[20] = flags[0];
    w[19] = (w[19] - w[20]);
    w[18] = (w[18] * w[19]);
    w[17] = (w[17] - w[18]);
    w[18] = gains[2];
    w[19] = x[1];
    w[20] = flags[1];
    w[19] = (w[19] - w[20]);
    w[18] = (w[18] * w[19]);
    w[17] = (w[17] - w[18]);
    w[18] = gains[1];
    w[19] = flags[2];
    w[19] = (w[1] - w[19]);
    w[18] = (w[18] * w[19]);
    w[17] = (w[17] - w[18]);
    w[18] = gains[0];
    w[19] = x[3];
    w[20] = flags[3];
    w[20] = (w[19] - w[20]);
    w[18] = (w[18] * w[20]);
    w[17] = (w[17] - w[18]);
    w[17] = (w[0] * w[17]);
    w[18] = x[7];
    w[20] = (w[1] * w[18]);
    w[21] = pvtol_control_sq(w[7]);
    w[22] = pvtol_control_sq(w[1]);
    w[22] = (w[21] + w[22]);
    w[23] = pvtol_control_sq(w[8]);
    w[22] = (w[22] + w[23]);
    w[23] = (2. * w[7]);
    w[24] = (w[23] * w[8]);
    w[22] = (w[22] + w[24]);
    w[20] = (w[20] / w[22]);
    w[24] = (w[7] * w[19]);
    w[24] = (w[24] / w[22]);
    w[20] = (w[20] - w[24]);
    w[24] = (w[19] * w[8]);
    w[24] = (w[24] / w[22]);
    w[20] = (w[20] - w[24]);
    w[24] = (w[1] * w[20]);
    w[25] = (w[7] * w[5]);
    w[26] = (w[25] * w[18]);
    w[22] = sqrt(w[22]);
    w[26] = (w[26] / w[22]);
    w[27] = (w[5] * w[1]);
    w[27] = (w[27] * w[19]);
    w[27] = (w[27] / w[22]);
    w[26] = (w[26] + w[27]);
    w[27] = (w[5] * w[8]);
    w[27] = (w[27] * w[18]);
    w[27] = (w[27] / w[22]);
    w[26] = (w[26] + w[27]);
    w[27] = (w[10] * w[26]);
    w[24] = (w[24] + w[27]);
    w[24] = (w[24] * w[20]);
    w[27] = (w[10] * w[20]);
    w[27] = (w[27] * w[26]);
    w[24] = (w[24] + w[27]);
    w[27] = (w[0] * w[24]);
    w[27] = (w[17] + w[27]);
    w[22] = (w[4] * w[27]);
    w[14] = (w[14] / w[12]);
    w[28] = flags[9];
    w[29] = gains[7];
    w[30] = x[4];
    w[31] = flags[5];
    w[30] = (w[30] - w[31]);
    w[29] = (w[29] * w[30]);
    w[28] = (w[28] - w[29]);
    w[29] = gains[6];
    w[30] = x[5];
    w[31] = flags[6];
    w[30] = (w[30] - w[31]);
    w[29] = (w[29] * w[30]);
    w[28] = (w[28] - w[29]);
    w[29] = gains[5];
    w[30] = flags[7];
    w[30] = (w[8] - w[30]);
    w[29] = (w[29] * w[30]);
    w[28] = (w[28] - w[29]);
    w[29] = gains[4];
    w[30] = flags[8];
    w[30] = (w[18] - w[30]);
    w[29] = (w[29] * w[30]);
    w[28] = (w[28] - w[29]);
    w[28] = (w[0] * w[28]);
    w[29] = (w[6] * w[26]);
    w[9] = (w[9] * w[20]);
    w[29] = (w[29] - w[9]);
    w[29] = (w[29] * w[20]);
    w[20] = (w[6] * w[20]);
    w[20] = (w[20] * w[26]);
    w[29] = (w[29] + w[20]);
    w[20] = (w[0] * w[29]);
    w[20] = (w[28] - w[20]);
    w[26] = (w[14] * w[20]);
    w[22] = (w[22] + w[26]);
    w[26] = (w[6] * w[22]);
    w[11] = (w[11] / w[12]);
    w[20] = (w[11] * w[20]);
    w[16] = (w[16] / w[12]);
    w[27] = (w[16] * w[27]);
    w[20] = (w[20] - w[27]);
    w[27] = -1.;
    w[20] = pvtol_control_fmax(w[20], w[27]);
    w[12] = 1.;
    w[20] = pvtol_control_fmin(w[20], w[12]);
    w[9] = (w[13] * w[20]);
    w[26] = (w[26] - w[9]);
    w[26] = (w[26] - w[24]);
    w[9] = (w[0] * w[26]);
    w[30] = 5.0000000000000001e-03;
    w[31] = (w[0] * w[19]);
    w[32] = 5.0000000000000002e-05;
    w[33] = (w[32] * w[26]);
    w[31] = (w[31] + w[33]);
    w[1] = (w[1] + w[31]);
    w[31] = (w[1] / w[5]);
    w[33] = (w[0] * w[18]);
    w[34] = (w[10] * w[22]);
    w[35] = (w[3] * w[20]);
    w[34] = (w[34] + w[35]);
    w[34] = (w[29] + w[34]);
    w[32] = (w[32] * w[34]);
    w[33] = (w[33] + w[32]);
    w[8] = (w[8] + w[33]);
    w[33] = (w[7] + w[8]);
    w[32] = pvtol_control_hypot(w[1], w[33]);
    w[31] = (w[31] / w[32]);
    w[35] = (w[31] * w[22]);
    w[36] = (w[33] / w[2]);
    w[36] = (w[36] * w[20]);
    w[35] = (w[35] - w[36]);
    w[0] = (w[0] * w[34]);
    w[18] = (w[18] + w[0]);
    w[36] = (w[1] * w[18]);
    w[37] = pvtol_control_sq(w[1]);
    w[21] = (w[21] + w[37]);
    w[37] = pvtol_control_sq(w[8]);
    w[21] = (w[21] + w[37]);
    w[23] = (w[23] * w[8]);
    w[21] = (w[21] + w[23]);
    w[36] = (w[36] / w[21]);
    w[19] = (w[19] + w[9]);
    w[7] = (w[7] * w[19]);
    w[7] = (w[7] / w[21]);
    w[36] = (w[36] - w[7]);
    w[7] = (w[19] * w[8]);
    w[7] = (w[7] / w[21]);
    w[36] = (w[36] - w[7]);
    w[7] = (w[1] * w[36]);
    w[15] = (w[15] / w[32]);
    w[15] = (w[15] * w[33]);
    w[25] = (w[25] * w[18]);
    w[21] = sqrt(w[21]);
    w[25] = (w[25] / w[21]);
    w[32] = (w[5] * w[1]);
    w[32] = (w[32] * w[19]);
    w[32] = (w[32] / w[21]);
    w[25] = (w[25] + w[32]);
    w[5] = (w[5] * w[8]);
    w[5] = (w[5] * w[18]);
    w[5] = (w[5] / w[21]);
    w[25] = (w[25] + w[5]);
    w[5] = (w[15] * w[25]);
    w[7] = (w[7] + w[5]);
    w[7] = (w[7] * w[36]);
    w[5] = (w[15] * w[36]);
    w[5] = (w[5] * w[25]);
    w[7] = (w[7] + w[5]);
    w[35] = (w[35] - w[7]);
    w[35] = (w[35] - w[26]);
    w[35] = (w[30] * w[35]);
    w[9] = (w[9] + w[35]);
    w[17] = (w[17] - w[9]);
    w[4] = (w[4] * w[17]);
    w[9] = (w[31] * w[25]);
    w[33] = (w[33] * w[36]);
    w[9] = (w[9] - w[33]);
    w[9] = (w[9] * w[36]);
    w[31] = (w[31] * w[36]);
    w[31] = (w[31] * w[25]);
    w[9] = (w[9] + w[31]);
    w[15] = (w[15] * w[22]);
    w[1] = (w[1] / w[2]);
    w[1] = (w[1] * w[20]);
    w[15] = (w[15] + w[1]);
    w[9] = (w[9] + w[15]);
    w[9] = (w[9] - w[34]);
    w[30] = (w[30] * w[9]);
    w[0] = (w[0] + w[30]);
    w[28] = (w[28] - w[0]);
    w[14] = (w[14] * w[28]);
    w[4] = (w[4] + w[14]);
    w[22] = (w[22] + w[4]);
    u[0] = w[22];
    w[11] = (w[11] * w[28]);
    w[16] = (w[16] * w[17]);
    w[11] = (w[11] - w[16]);
    w[20] = (w[20] + w[11]);
    w[11] = pvtol_control_fmax(w[20], w[27]);
    w[11] = pvtol_control_fmin(w[11], w[12]);
    u[1] = w[11];
    w[16] = (w[6] * w[22]);
    w[17] = (w[13] * w[11]);
    w[16] = (w[16] - w[17]);
    w[16] = (w[16] - w[24]);
    v[0] = w[16];
    w[22] = (w[10] * w[22]);
    w[11] = (w[3] * w[11]);
    w[22] = (w[22] + w[11]);
    w[29] = (w[29] + w[22]);
    v[1] = w[29];
    w[6] = (w[6] * w[3]);
    w[13] = (w[13] * w[10]);
    w[6] = (w[6] + w[13]);
    det[0] = w[6];
    w[27] = (w[20] < w[27]);
    w[12] = (w[12] < w[20]);
    w[27] = (w[27] + w[12]);
    nsat[0] = w[27];
    return 0;
    return 0;
}
