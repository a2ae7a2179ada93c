/* DO NOT EDIT: dc_motor_link module, generated from template kernels.c.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* Node filter kernels (the master reuses predict): node_predict, update, info, predict.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only); a
 * kernel that is another on packed copies of its matrices is that call between two copy loops. */
#include <math.h>
#include "dc_motor_link_internal.h"

static dc_motor_link_real casadi_sq(dc_motor_link_real x)
{
    return x * x;
}

/* dc_motor_link_kern_node_predict:(post[9],v,q)->(x1[3],P1[6]) */
int dc_motor_link_kern_node_predict(const dc_motor_link_real post[9], const dc_motor_link_real v[1],
                                    const dc_motor_link_real q[1], dc_motor_link_real x1[3],
                                    dc_motor_link_real P1[6])
{
    dc_motor_link_real w[11];
    w[0] = post[0];
    w[1] = 1.0000000000000000e-02;
    w[2] = post[1];
    w[3] = (w[1] * w[2]);
    w[0] = (w[0] + w[3]);
    w[3] = 5.0000000000000002e-05;
    w[4] = post[2];
    w[5] = (w[3] * w[4]);
    w[0] = (w[0] + w[5]);
    w[5] = 1.6666666666666670e-07;
    w[6] = v[0];
    w[7] = (w[5] * w[6]);
    w[0] = (w[0] + w[7]);
    x1[0] = w[0];
    w[0] = (w[1] * w[4]);
    w[2] = (w[2] + w[0]);
    w[0] = (w[3] * w[6]);
    w[2] = (w[2] + w[0]);
    x1[1] = w[2];
    w[6] = (w[1] * w[6]);
    w[4] = (w[4] + w[6]);
    x1[2] = w[4];
    w[4] = post[3];
    w[6] = post[4];
    w[2] = (w[1] * w[6]);
    w[4] = (w[4] + w[2]);
    w[2] = post[6];
    w[0] = (w[3] * w[2]);
    w[4] = (w[4] + w[0]);
    w[0] = post[5];
    w[7] = (w[1] * w[0]);
    w[6] = (w[6] + w[7]);
    w[7] = post[7];
    w[8] = (w[3] * w[7]);
    w[6] = (w[6] + w[8]);
    w[8] = (w[1] * w[6]);
    w[4] = (w[4] + w[8]);
    w[8] = (w[1] * w[7]);
    w[2] = (w[2] + w[8]);
    w[8] = post[8];
    w[9] = (w[3] * w[8]);
    w[2] = (w[2] + w[9]);
    w[9] = (w[3] * w[2]);
    w[4] = (w[4] + w[9]);
    w[9] = 5.0000000000000005e-12;
    w[10] = q[0];
    w[9] = (w[9] * w[10]);
    w[4] = (w[4] + w[9]);
    P1[0] = w[4];
    w[4] = (w[1] * w[2]);
    w[6] = (w[6] + w[4]);
    w[4] = 1.2500000000000000e-09;
    w[4] = (w[4] * w[10]);
    w[6] = (w[6] + w[4]);
    P1[1] = w[6];
    w[6] = (w[1] * w[7]);
    w[0] = (w[0] + w[6]);
    w[6] = (w[1] * w[8]);
    w[7] = (w[7] + w[6]);
    w[6] = (w[1] * w[7]);
    w[0] = (w[0] + w[6]);
    w[6] = 3.3333333333333341e-07;
    w[6] = (w[6] * w[10]);
    w[0] = (w[0] + w[6]);
    P1[2] = w[0];
    w[5] = (w[5] * w[10]);
    w[2] = (w[2] + w[5]);
    P1[3] = w[2];
    w[3] = (w[3] * w[10]);
    w[7] = (w[7] + w[3]);
    P1[4] = w[7];
    w[1] = (w[1] * w[10]);
    w[8] = (w[8] + w[1]);
    P1[5] = w[8];
    return 0;
    return 0;
}

/* dc_motor_link_kern_update:(prior[9],e,R)->(post[9],piv) */
int dc_motor_link_kern_update(const dc_motor_link_real prior[9], const dc_motor_link_real e[1],
                              const dc_motor_link_real R[1], dc_motor_link_real post[9],
                              dc_motor_link_real piv[1])
{
    dc_motor_link_real w[9];
    w[0] = prior[0];
    w[1] = prior[3];
    w[2] = R[0];
    w[3] = (w[1] + w[2]);
    w[1] = (w[1] / w[3]);
    w[4] = e[0];
    w[5] = (w[1] * w[4]);
    w[0] = (w[0] + w[5]);
    post[0] = w[0];
    w[0] = prior[1];
    w[5] = prior[4];
    w[6] = (w[5] / w[3]);
    w[7] = (w[6] * w[4]);
    w[0] = (w[0] + w[7]);
    post[1] = w[0];
    w[0] = prior[2];
    w[7] = prior[6];
    w[8] = (w[7] / w[3]);
    w[4] = (w[8] * w[4]);
    w[0] = (w[0] + w[4]);
    post[2] = w[0];
    w[1] = (w[2] * w[1]);
    post[3] = w[1];
    w[1] = (w[2] * w[6]);
    post[4] = w[1];
    w[1] = prior[5];
    w[5] = (w[6] * w[5]);
    w[1] = (w[1] - w[5]);
    post[5] = w[1];
    w[2] = (w[2] * w[8]);
    post[6] = w[2];
    w[2] = prior[7];
    w[6] = (w[6] * w[7]);
    w[2] = (w[2] - w[6]);
    post[7] = w[2];
    w[2] = prior[8];
    w[8] = (w[8] * w[7]);
    w[2] = (w[2] - w[8]);
    post[8] = w[2];
    piv[0] = w[3];
    return 0;
    return 0;
}

/* dc_motor_link_kern_info:(x[3],P[3x3],c[3])->(Y[3x3],y[3],piv[3]) */
int dc_motor_link_kern_info(const dc_motor_link_real x[3], const dc_motor_link_real P[9],
                            const dc_motor_link_real c[3], dc_motor_link_real Y[9],
                            dc_motor_link_real y[3], dc_motor_link_real piv[3])
{
    dc_motor_link_real w[12];
    w[0] = P[0];
    w[1] = (1. / w[0]);
    w[2] = P[1];
    w[3] = sqrt(w[1]);
    w[2] = (w[2] * w[3]);
    w[4] = (w[2] * w[3]);
    w[5] = P[4];
    w[6] = casadi_sq(w[2]);
    w[5] = (w[5] - w[6]);
    w[6] = (1. / w[5]);
    w[7] = sqrt(w[6]);
    w[4] = (w[4] * w[7]);
    w[8] = casadi_sq(w[4]);
    w[1] = (w[1] + w[8]);
    w[8] = P[2];
    w[8] = (w[8] * w[3]);
    w[3] = (w[8] * w[3]);
    w[9] = P[5];
    w[2] = (w[8] * w[2]);
    w[9] = (w[9] - w[2]);
    w[9] = (w[9] * w[7]);
    w[2] = (w[9] * w[4]);
    w[3] = (w[3] - w[2]);
    w[2] = P[8];
    w[8] = casadi_sq(w[8]);
    w[2] = (w[2] - w[8]);
    w[8] = casadi_sq(w[9]);
    w[2] = (w[2] - w[8]);
    w[8] = (1. / w[2]);
    w[10] = sqrt(w[8]);
    w[3] = (w[3] * w[10]);
    w[11] = casadi_sq(w[3]);
    w[1] = (w[1] + w[11]);
    Y[0] = w[1];
    w[9] = (w[9] * w[7]);
    w[9] = (w[9] * w[10]);
    w[11] = (w[3] * w[9]);
    w[4] = (w[4] * w[7]);
    w[11] = (w[11] - w[4]);
    Y[1] = w[11];
    w[3] = (w[3] * w[10]);
    w[4] = (-w[3]);
    Y[2] = w[4];
    Y[3] = w[11];
    w[7] = casadi_sq(w[9]);
    w[6] = (w[6] + w[7]);
    Y[4] = w[6];
    w[9] = (w[9] * w[10]);
    w[10] = (-w[9]);
    Y[5] = w[10];
    Y[6] = w[4];
    Y[7] = w[10];
    Y[8] = w[8];
    w[8] = x[0];
    w[10] = c[0];
    w[8] = (w[8] - w[10]);
    w[1] = (w[1] * w[8]);
    w[10] = x[1];
    w[4] = c[1];
    w[10] = (w[10] - w[4]);
    w[4] = (w[11] * w[10]);
    w[1] = (w[1] + w[4]);
    w[4] = x[2];
    w[7] = c[2];
    w[4] = (w[4] - w[7]);
    w[7] = (w[3] * w[4]);
    w[1] = (w[1] - w[7]);
    y[0] = w[1];
    w[11] = (w[11] * w[8]);
    w[6] = (w[6] * w[10]);
    w[11] = (w[11] + w[6]);
    w[6] = (w[9] * w[4]);
    w[11] = (w[11] - w[6]);
    y[1] = w[11];
    w[4] = (w[4] / w[2]);
    w[3] = (w[3] * w[8]);
    w[9] = (w[9] * w[10]);
    w[3] = (w[3] + w[9]);
    w[4] = (w[4] - w[3]);
    y[2] = w[4];
    piv[0] = w[0];
    piv[1] = w[5];
    piv[2] = w[2];
    return 0;
    return 0;
}

/* dc_motor_link_kern_predict:(x[3],P[3x3],v,q)->(x1[3],P1[3x3]) */
int dc_motor_link_kern_predict(const dc_motor_link_real x[3], const dc_motor_link_real P[9],
                               const dc_motor_link_real v[1], const dc_motor_link_real q[1],
                               dc_motor_link_real x1[3], dc_motor_link_real P1[9])
{
    dc_motor_link_real post_packed[9];
    dc_motor_link_real P1_packed[6];
    int i;
    int j;
    int k;
    for (i = 0; i < 3; i++) {
        post_packed[i] = x[i];
    }
    k = 0;
    for (j = 0; j < 3; j++) {
        for (i = 0; i <= j; i++) {
            post_packed[3 + k] = P[(j * 3) + i];
            k++;
        }
    }
    (void)dc_motor_link_kern_node_predict(post_packed, v, q, x1, P1_packed);
    k = 0;
    for (j = 0; j < 3; j++) {
        for (i = 0; i <= j; i++) {
            P1[(j * 3) + i] = P1_packed[k];
            P1[(i * 3) + j] = P1_packed[k];
            k++;
        }
    }
    return 0;
}
