/* DO NOT EDIT: dc_motor_link module, generated from template kernels.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* Master fusion kernels: fuse_finish.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only). */
#include <math.h>
#include "dc_motor_link_internal.h"

static dc_motor_link_real dc_motor_link_fusion_sq(dc_motor_link_real x)
{
    return x * x;
}

/* dc_motor_link_kern_fuse_finish:(Y[3x3],y[3],c[3])->(x[3],P[3x3],piv[3]) */
int dc_motor_link_kern_fuse_finish(const dc_motor_link_real Y[9], const dc_motor_link_real y[3],
                                   const dc_motor_link_real c[3], dc_motor_link_real x[3],
                                   dc_motor_link_real P[9], dc_motor_link_real piv[3],
                                   dc_motor_link_real w[18])
{
    w[0] = c[0];
    w[1] = Y[0];
    w[2] = sqrt(w[1]);
    w[3] = (1. / w[2]);
    w[3] = dc_motor_link_fusion_sq(w[3]);
    w[4] = Y[1];
    w[4] = (w[4] / w[2]);
    w[5] = (w[4] / w[2]);
    w[6] = Y[4];
    w[7] = dc_motor_link_fusion_sq(w[4]);
    w[6] = (w[6] - w[7]);
    w[7] = sqrt(w[6]);
    w[5] = (w[5] / w[7]);
    w[8] = dc_motor_link_fusion_sq(w[5]);
    w[3] = (w[3] + w[8]);
    w[8] = Y[5];
    w[9] = Y[2];
    w[9] = (w[9] / w[2]);
    w[4] = (w[9] * w[4]);
    w[8] = (w[8] - w[4]);
    w[8] = (w[8] / w[7]);
    w[4] = (w[8] * w[5]);
    w[2] = (w[9] / w[2]);
    w[4] = (w[4] - w[2]);
    w[2] = Y[8];
    w[9] = dc_motor_link_fusion_sq(w[9]);
    w[2] = (w[2] - w[9]);
    w[9] = dc_motor_link_fusion_sq(w[8]);
    w[2] = (w[2] - w[9]);
    w[9] = sqrt(w[2]);
    w[4] = (w[4] / w[9]);
    w[10] = dc_motor_link_fusion_sq(w[4]);
    w[3] = (w[3] + w[10]);
    w[10] = y[0];
    w[11] = (w[3] * w[10]);
    w[12] = (w[5] / w[7]);
    w[8] = (w[8] / w[7]);
    w[8] = (w[8] / w[9]);
    w[13] = (w[4] * w[8]);
    w[12] = (w[12] + w[13]);
    w[13] = y[1];
    w[14] = (w[12] * w[13]);
    w[11] = (w[11] - w[14]);
    w[14] = (w[4] / w[9]);
    w[15] = y[2];
    w[16] = (w[14] * w[15]);
    w[11] = (w[11] + w[16]);
    w[0] = (w[0] + w[11]);
    x[0] = w[0];
    w[0] = c[1];
    w[11] = (1. / w[7]);
    w[11] = dc_motor_link_fusion_sq(w[11]);
    w[16] = dc_motor_link_fusion_sq(w[8]);
    w[11] = (w[11] + w[16]);
    w[16] = (w[11] * w[13]);
    w[5] = (w[5] / w[7]);
    w[7] = (w[8] * w[4]);
    w[5] = (w[5] + w[7]);
    w[7] = (w[5] * w[10]);
    w[16] = (w[16] - w[7]);
    w[7] = (w[8] / w[9]);
    w[17] = (w[7] * w[15]);
    w[16] = (w[16] - w[17]);
    w[0] = (w[0] + w[16]);
    x[1] = w[0];
    w[0] = c[2];
    w[4] = (w[4] / w[9]);
    w[10] = (w[4] * w[10]);
    w[8] = (w[8] / w[9]);
    w[13] = (w[8] * w[13]);
    w[10] = (w[10] - w[13]);
    w[9] = (1. / w[9]);
    w[9] = dc_motor_link_fusion_sq(w[9]);
    w[15] = (w[9] * w[15]);
    w[10] = (w[10] + w[15]);
    w[0] = (w[0] + w[10]);
    x[2] = w[0];
    P[0] = w[3];
    w[5] = (-w[5]);
    P[1] = w[5];
    P[2] = w[4];
    w[12] = (-w[12]);
    P[3] = w[12];
    P[4] = w[11];
    w[8] = (-w[8]);
    P[5] = w[8];
    P[6] = w[14];
    w[7] = (-w[7]);
    P[7] = w[7];
    P[8] = w[9];
    piv[0] = w[1];
    piv[1] = w[6];
    piv[2] = w[2];
    return 0;
    return 0;
}
