/* DO NOT EDIT: unicycle module, generated from template kernels.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build unicycle`. */
/* Node filter kernels (the master reuses predict): node_predict, update, info, node_predict_P,
 * domain, noise, predict.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only); a
 * kernel that is another on packed copies of its matrices is that call between two copy loops. */
#include <math.h>
#include "unicycle_internal.h"

static unicycle_real casadi_hypot(unicycle_real x, unicycle_real y)
{
    return hypot(x, y);
}

static unicycle_real casadi_sq(unicycle_real x)
{
    return x * x;
}

/* unicycle_kern_node_predict:(post[14],u[2],Q[10],centre[2])->(x1[4],P1[10]) */
int unicycle_kern_node_predict(const unicycle_real post[14], const unicycle_real u[2],
                               const unicycle_real Q[10], const unicycle_real centre[2],
                               unicycle_real x1[4], unicycle_real P1[10])
{
    (void)centre;
    unicycle_real w[17];
    w[0] = post[0];
    w[1] = 2.0000000000000000e-02;
    w[2] = post[1];
    w[3] = (w[1] * w[2]);
    w[4] = 2.0000000000000001e-04;
    w[5] = post[3];
    w[6] = casadi_hypot(w[2], w[5]);
    w[6] = (w[2] / w[6]);
    w[7] = u[0];
    w[6] = (w[6] * w[7]);
    w[8] = u[1];
    w[9] = (w[5] * w[8]);
    w[6] = (w[6] - w[9]);
    w[9] = (w[4] * w[6]);
    w[3] = (w[3] + w[9]);
    w[9] = 6.6666666666666683e-05;
    w[10] = (w[1] * w[6]);
    w[11] = (w[2] + w[10]);
    w[12] = casadi_hypot(w[2], w[5]);
    w[12] = (w[5] / w[12]);
    w[12] = (w[12] * w[7]);
    w[13] = (w[2] * w[8]);
    w[12] = (w[12] + w[13]);
    w[13] = (w[1] * w[12]);
    w[14] = (w[5] + w[13]);
    w[15] = casadi_hypot(w[11], w[14]);
    w[15] = (w[11] / w[15]);
    w[15] = (w[15] * w[7]);
    w[16] = (w[14] * w[8]);
    w[15] = (w[15] - w[16]);
    w[15] = (w[15] - w[6]);
    w[6] = (w[9] * w[15]);
    w[3] = (w[3] + w[6]);
    w[0] = (w[0] + w[3]);
    x1[0] = w[0];
    w[0] = 1.0000000000000000e-02;
    w[15] = (w[0] * w[15]);
    w[10] = (w[10] + w[15]);
    w[2] = (w[2] + w[10]);
    x1[1] = w[2];
    w[2] = post[2];
    w[10] = (w[1] * w[5]);
    w[4] = (w[4] * w[12]);
    w[10] = (w[10] + w[4]);
    w[4] = casadi_hypot(w[11], w[14]);
    w[14] = (w[14] / w[4]);
    w[14] = (w[14] * w[7]);
    w[11] = (w[11] * w[8]);
    w[14] = (w[14] + w[11]);
    w[14] = (w[14] - w[12]);
    w[9] = (w[9] * w[14]);
    w[10] = (w[10] + w[9]);
    w[2] = (w[2] + w[10]);
    x1[2] = w[2];
    w[0] = (w[0] * w[14]);
    w[13] = (w[13] + w[0]);
    w[5] = (w[5] + w[13]);
    x1[3] = w[5];
    w[5] = post[4];
    w[13] = post[5];
    w[0] = (w[1] * w[13]);
    w[5] = (w[5] + w[0]);
    w[0] = post[6];
    w[14] = (w[1] * w[0]);
    w[13] = (w[13] + w[14]);
    w[14] = (w[1] * w[13]);
    w[5] = (w[5] + w[14]);
    w[14] = Q[0];
    w[5] = (w[5] + w[14]);
    P1[0] = w[5];
    w[5] = Q[1];
    w[13] = (w[13] + w[5]);
    P1[1] = w[13];
    w[13] = Q[2];
    w[0] = (w[0] + w[13]);
    P1[2] = w[0];
    w[0] = post[7];
    w[13] = post[8];
    w[5] = (w[1] * w[13]);
    w[0] = (w[0] + w[5]);
    w[5] = post[10];
    w[14] = post[11];
    w[2] = (w[1] * w[14]);
    w[5] = (w[5] + w[2]);
    w[2] = (w[1] * w[5]);
    w[0] = (w[0] + w[2]);
    P1[3] = w[0];
    w[0] = (w[1] * w[14]);
    w[13] = (w[13] + w[0]);
    P1[4] = w[13];
    w[13] = post[9];
    w[0] = post[12];
    w[2] = (w[1] * w[0]);
    w[13] = (w[13] + w[2]);
    w[2] = post[13];
    w[10] = (w[1] * w[2]);
    w[0] = (w[0] + w[10]);
    w[1] = (w[1] * w[0]);
    w[13] = (w[13] + w[1]);
    w[1] = Q[5];
    w[13] = (w[13] + w[1]);
    P1[5] = w[13];
    P1[6] = w[5];
    P1[7] = w[14];
    w[14] = Q[8];
    w[0] = (w[0] + w[14]);
    P1[8] = w[0];
    w[0] = Q[9];
    w[2] = (w[2] + w[0]);
    P1[9] = w[2];
    return 0;
    return 0;
}

/* unicycle_kern_update:(prior[14],e[2],R[2x2])->(post[14],piv[2]) */
int unicycle_kern_update(const unicycle_real prior[14], const unicycle_real e[2],
                         const unicycle_real R[4], unicycle_real post[14], unicycle_real piv[2])
{
    unicycle_real w[22];
    w[0] = prior[0];
    w[1] = prior[4];
    w[2] = R[0];
    w[3] = (w[1] + w[2]);
    w[4] = sqrt(w[3]);
    w[5] = (1. / w[4]);
    w[5] = casadi_sq(w[5]);
    w[6] = prior[7];
    w[7] = R[1];
    w[8] = (w[6] + w[7]);
    w[8] = (w[8] / w[4]);
    w[4] = (w[8] / w[4]);
    w[9] = prior[9];
    w[10] = R[3];
    w[11] = (w[9] + w[10]);
    w[8] = casadi_sq(w[8]);
    w[11] = (w[11] - w[8]);
    w[8] = sqrt(w[11]);
    w[4] = (w[4] / w[8]);
    w[12] = casadi_sq(w[4]);
    w[5] = (w[5] + w[12]);
    w[12] = (w[1] * w[5]);
    w[13] = (w[4] / w[8]);
    w[14] = (w[6] * w[13]);
    w[12] = (w[12] - w[14]);
    w[14] = e[0];
    w[15] = (w[12] * w[14]);
    w[16] = (1. / w[8]);
    w[16] = casadi_sq(w[16]);
    w[17] = (w[6] * w[16]);
    w[4] = (w[4] / w[8]);
    w[1] = (w[1] * w[4]);
    w[17] = (w[17] - w[1]);
    w[1] = e[1];
    w[8] = (w[17] * w[1]);
    w[15] = (w[15] + w[8]);
    w[0] = (w[0] + w[15]);
    post[0] = w[0];
    w[0] = prior[1];
    w[15] = prior[5];
    w[8] = (w[15] * w[5]);
    w[18] = prior[8];
    w[19] = (w[18] * w[13]);
    w[8] = (w[8] - w[19]);
    w[19] = (w[8] * w[14]);
    w[20] = (w[18] * w[16]);
    w[21] = (w[15] * w[4]);
    w[20] = (w[20] - w[21]);
    w[21] = (w[20] * w[1]);
    w[19] = (w[19] + w[21]);
    w[0] = (w[0] + w[19]);
    post[1] = w[0];
    w[0] = prior[2];
    w[19] = (w[6] * w[5]);
    w[21] = (w[9] * w[13]);
    w[19] = (w[19] - w[21]);
    w[21] = (w[19] * w[14]);
    w[9] = (w[9] * w[16]);
    w[6] = (w[6] * w[4]);
    w[9] = (w[9] - w[6]);
    w[6] = (w[9] * w[1]);
    w[21] = (w[21] + w[6]);
    w[0] = (w[0] + w[21]);
    post[2] = w[0];
    w[0] = prior[3];
    w[21] = prior[10];
    w[5] = (w[21] * w[5]);
    w[6] = prior[12];
    w[13] = (w[6] * w[13]);
    w[5] = (w[5] - w[13]);
    w[14] = (w[5] * w[14]);
    w[16] = (w[6] * w[16]);
    w[4] = (w[21] * w[4]);
    w[16] = (w[16] - w[4]);
    w[1] = (w[16] * w[1]);
    w[14] = (w[14] + w[1]);
    w[0] = (w[0] + w[14]);
    post[3] = w[0];
    w[0] = (w[2] * w[12]);
    w[14] = R[2];
    w[1] = (w[14] * w[17]);
    w[0] = (w[0] + w[1]);
    post[4] = w[0];
    w[0] = (w[2] * w[8]);
    w[1] = (w[14] * w[20]);
    w[0] = (w[0] + w[1]);
    post[5] = w[0];
    w[0] = prior[6];
    w[15] = (w[8] * w[15]);
    w[18] = (w[20] * w[18]);
    w[15] = (w[15] + w[18]);
    w[0] = (w[0] - w[15]);
    post[6] = w[0];
    w[12] = (w[7] * w[12]);
    w[17] = (w[10] * w[17]);
    w[12] = (w[12] + w[17]);
    post[7] = w[12];
    w[12] = (w[7] * w[8]);
    w[17] = (w[10] * w[20]);
    w[12] = (w[12] + w[17]);
    post[8] = w[12];
    w[19] = (w[7] * w[19]);
    w[9] = (w[10] * w[9]);
    w[19] = (w[19] + w[9]);
    post[9] = w[19];
    w[2] = (w[2] * w[5]);
    w[14] = (w[14] * w[16]);
    w[2] = (w[2] + w[14]);
    post[10] = w[2];
    w[2] = prior[11];
    w[8] = (w[8] * w[21]);
    w[20] = (w[20] * w[6]);
    w[8] = (w[8] + w[20]);
    w[2] = (w[2] - w[8]);
    post[11] = w[2];
    w[7] = (w[7] * w[5]);
    w[10] = (w[10] * w[16]);
    w[7] = (w[7] + w[10]);
    post[12] = w[7];
    w[7] = prior[13];
    w[5] = (w[5] * w[21]);
    w[16] = (w[16] * w[6]);
    w[5] = (w[5] + w[16]);
    w[7] = (w[7] - w[5]);
    post[13] = w[7];
    piv[0] = w[3];
    piv[1] = w[11];
    return 0;
    return 0;
}

/* unicycle_kern_info:(x[4],P[4x4],c[4])->(Y[4x4],y[4],piv[4]) */
int unicycle_kern_info(const unicycle_real x[4], const unicycle_real P[16],
                       const unicycle_real c[4], unicycle_real Y[16], unicycle_real y[4],
                       unicycle_real piv[4])
{
    unicycle_real w[18];
    w[0] = P[0];
    w[1] = (1. / w[0]);
    w[2] = P[1];
    w[3] = sqrt(w[1]);
    w[2] = (w[2] * w[3]);
    w[4] = (w[2] * w[3]);
    w[5] = P[5];
    w[6] = casadi_sq(w[2]);
    w[5] = (w[5] - w[6]);
    w[6] = (1. / w[5]);
    w[7] = sqrt(w[6]);
    w[4] = (w[4] * w[7]);
    w[8] = casadi_sq(w[4]);
    w[1] = (w[1] + w[8]);
    w[8] = P[2];
    w[8] = (w[8] * w[3]);
    w[9] = (w[8] * w[3]);
    w[10] = P[6];
    w[11] = (w[8] * w[2]);
    w[10] = (w[10] - w[11]);
    w[10] = (w[10] * w[7]);
    w[11] = (w[10] * w[4]);
    w[9] = (w[9] - w[11]);
    w[11] = P[10];
    w[12] = casadi_sq(w[8]);
    w[11] = (w[11] - w[12]);
    w[12] = casadi_sq(w[10]);
    w[11] = (w[11] - w[12]);
    w[12] = (1. / w[11]);
    w[13] = sqrt(w[12]);
    w[9] = (w[9] * w[13]);
    w[14] = casadi_sq(w[9]);
    w[1] = (w[1] + w[14]);
    w[14] = P[3];
    w[14] = (w[14] * w[3]);
    w[3] = (w[14] * w[3]);
    w[15] = P[7];
    w[2] = (w[14] * w[2]);
    w[15] = (w[15] - w[2]);
    w[15] = (w[15] * w[7]);
    w[2] = (w[15] * w[4]);
    w[3] = (w[3] - w[2]);
    w[2] = P[11];
    w[8] = (w[14] * w[8]);
    w[2] = (w[2] - w[8]);
    w[8] = (w[15] * w[10]);
    w[2] = (w[2] - w[8]);
    w[2] = (w[2] * w[13]);
    w[8] = (w[2] * w[9]);
    w[3] = (w[3] - w[8]);
    w[8] = P[15];
    w[14] = casadi_sq(w[14]);
    w[8] = (w[8] - w[14]);
    w[14] = casadi_sq(w[15]);
    w[8] = (w[8] - w[14]);
    w[14] = casadi_sq(w[2]);
    w[8] = (w[8] - w[14]);
    w[14] = (1. / w[8]);
    w[16] = sqrt(w[14]);
    w[3] = (w[3] * w[16]);
    w[17] = casadi_sq(w[3]);
    w[1] = (w[1] + w[17]);
    Y[0] = w[1];
    w[10] = (w[10] * w[7]);
    w[10] = (w[10] * w[13]);
    w[17] = (w[9] * w[10]);
    w[4] = (w[4] * w[7]);
    w[17] = (w[17] - w[4]);
    w[15] = (w[15] * w[7]);
    w[7] = (w[2] * w[10]);
    w[15] = (w[15] - w[7]);
    w[15] = (w[15] * w[16]);
    w[7] = (w[3] * w[15]);
    w[17] = (w[17] + w[7]);
    Y[1] = w[17];
    w[2] = (w[2] * w[13]);
    w[2] = (w[2] * w[16]);
    w[7] = (w[3] * w[2]);
    w[9] = (w[9] * w[13]);
    w[7] = (w[7] - w[9]);
    Y[2] = w[7];
    w[3] = (w[3] * w[16]);
    w[9] = (-w[3]);
    Y[3] = w[9];
    Y[4] = w[17];
    w[4] = casadi_sq(w[10]);
    w[6] = (w[6] + w[4]);
    w[4] = casadi_sq(w[15]);
    w[6] = (w[6] + w[4]);
    Y[5] = w[6];
    w[4] = (w[15] * w[2]);
    w[10] = (w[10] * w[13]);
    w[4] = (w[4] - w[10]);
    Y[6] = w[4];
    w[15] = (w[15] * w[16]);
    w[10] = (-w[15]);
    Y[7] = w[10];
    Y[8] = w[7];
    Y[9] = w[4];
    w[13] = casadi_sq(w[2]);
    w[12] = (w[12] + w[13]);
    Y[10] = w[12];
    w[2] = (w[2] * w[16]);
    w[16] = (-w[2]);
    Y[11] = w[16];
    Y[12] = w[9];
    Y[13] = w[10];
    Y[14] = w[16];
    Y[15] = w[14];
    w[14] = x[0];
    w[16] = c[0];
    w[14] = (w[14] - w[16]);
    w[1] = (w[1] * w[14]);
    w[16] = x[1];
    w[10] = c[1];
    w[16] = (w[16] - w[10]);
    w[10] = (w[17] * w[16]);
    w[1] = (w[1] + w[10]);
    w[10] = x[2];
    w[9] = c[2];
    w[10] = (w[10] - w[9]);
    w[9] = (w[7] * w[10]);
    w[1] = (w[1] + w[9]);
    w[9] = x[3];
    w[13] = c[3];
    w[9] = (w[9] - w[13]);
    w[13] = (w[3] * w[9]);
    w[1] = (w[1] - w[13]);
    y[0] = w[1];
    w[17] = (w[17] * w[14]);
    w[6] = (w[6] * w[16]);
    w[17] = (w[17] + w[6]);
    w[6] = (w[4] * w[10]);
    w[17] = (w[17] + w[6]);
    w[6] = (w[15] * w[9]);
    w[17] = (w[17] - w[6]);
    y[1] = w[17];
    w[7] = (w[7] * w[14]);
    w[4] = (w[4] * w[16]);
    w[7] = (w[7] + w[4]);
    w[12] = (w[12] * w[10]);
    w[7] = (w[7] + w[12]);
    w[12] = (w[2] * w[9]);
    w[7] = (w[7] - w[12]);
    y[2] = w[7];
    w[9] = (w[9] / w[8]);
    w[3] = (w[3] * w[14]);
    w[15] = (w[15] * w[16]);
    w[3] = (w[3] + w[15]);
    w[2] = (w[2] * w[10]);
    w[3] = (w[3] + w[2]);
    w[9] = (w[9] - w[3]);
    y[3] = w[9];
    piv[0] = w[0];
    piv[1] = w[5];
    piv[2] = w[11];
    piv[3] = w[8];
    return 0;
    return 0;
}

/* unicycle_kern_node_predict_P:(P[10],Q[10])->(P1[10]) */
int unicycle_kern_node_predict_P(const unicycle_real P[10], const unicycle_real Q[10],
                                 unicycle_real P1[10])
{
    unicycle_real w[7];
    w[0] = P[0];
    w[1] = 2.0000000000000000e-02;
    w[2] = P[1];
    w[3] = (w[1] * w[2]);
    w[0] = (w[0] + w[3]);
    w[3] = P[2];
    w[4] = (w[1] * w[3]);
    w[2] = (w[2] + w[4]);
    w[4] = (w[1] * w[2]);
    w[0] = (w[0] + w[4]);
    w[4] = Q[0];
    w[0] = (w[0] + w[4]);
    P1[0] = w[0];
    w[0] = Q[1];
    w[2] = (w[2] + w[0]);
    P1[1] = w[2];
    w[2] = Q[2];
    w[3] = (w[3] + w[2]);
    P1[2] = w[3];
    w[3] = P[3];
    w[2] = P[4];
    w[0] = (w[1] * w[2]);
    w[3] = (w[3] + w[0]);
    w[0] = P[6];
    w[4] = P[7];
    w[5] = (w[1] * w[4]);
    w[0] = (w[0] + w[5]);
    w[5] = (w[1] * w[0]);
    w[3] = (w[3] + w[5]);
    P1[3] = w[3];
    w[3] = (w[1] * w[4]);
    w[2] = (w[2] + w[3]);
    P1[4] = w[2];
    w[2] = P[5];
    w[3] = P[8];
    w[5] = (w[1] * w[3]);
    w[2] = (w[2] + w[5]);
    w[5] = P[9];
    w[6] = (w[1] * w[5]);
    w[3] = (w[3] + w[6]);
    w[1] = (w[1] * w[3]);
    w[2] = (w[2] + w[1]);
    w[1] = Q[5];
    w[2] = (w[2] + w[1]);
    P1[5] = w[2];
    P1[6] = w[0];
    P1[7] = w[4];
    w[4] = Q[8];
    w[3] = (w[3] + w[4]);
    P1[8] = w[3];
    w[3] = Q[9];
    w[5] = (w[5] + w[3]);
    P1[9] = w[5];
    return 0;
    return 0;
}

/* unicycle_kern_domain:(x[4])->(F[2],G[2x2]) */
int unicycle_kern_domain(const unicycle_real x[4], unicycle_real F[2], unicycle_real G[4])
{
    unicycle_real w[3];
    w[0] = 0.;
    F[0] = w[0];
    F[1] = w[0];
    w[0] = x[1];
    w[1] = x[3];
    w[2] = casadi_hypot(w[0], w[1]);
    w[2] = (w[0] / w[2]);
    G[0] = w[2];
    w[2] = casadi_hypot(w[0], w[1]);
    w[2] = (w[1] / w[2]);
    G[1] = w[2];
    w[1] = (-w[1]);
    G[2] = w[1];
    G[3] = w[0];
    return 0;
    return 0;
}

/* unicycle_kern_noise:(q[2])->(Q[10]) */
int unicycle_kern_noise(const unicycle_real q[2], unicycle_real Q[10])
{
    unicycle_real w[5];
    w[0] = 2.6666666666666668e-06;
    w[1] = q[0];
    w[2] = (w[0] * w[1]);
    Q[0] = w[2];
    w[2] = 2.0000000000000001e-04;
    w[3] = (w[2] * w[1]);
    Q[1] = w[3];
    w[3] = 2.0000000000000000e-02;
    w[1] = (w[3] * w[1]);
    Q[2] = w[1];
    w[1] = 0.;
    Q[3] = w[1];
    Q[4] = w[1];
    w[4] = q[1];
    w[0] = (w[0] * w[4]);
    Q[5] = w[0];
    Q[6] = w[1];
    Q[7] = w[1];
    w[2] = (w[2] * w[4]);
    Q[8] = w[2];
    w[3] = (w[3] * w[4]);
    Q[9] = w[3];
    return 0;
    return 0;
}

/* unicycle_kern_predict:(x[4],P[4x4],u[2],Q[10],centre[2])->(x1[4],P1[4x4]) */
int unicycle_kern_predict(const unicycle_real x[4], const unicycle_real P[16],
                          const unicycle_real u[2], const unicycle_real Q[10],
                          const unicycle_real centre[2], unicycle_real x1[4], unicycle_real P1[16])
{
    unicycle_real post_packed[14];
    unicycle_real P1_packed[10];
    int i;
    int j;
    int k;
    for (i = 0; i < 4; i++) {
        post_packed[i] = x[i];
    }
    k = 0;
    for (j = 0; j < 4; j++) {
        for (i = 0; i <= j; i++) {
            post_packed[4 + k] = P[(j * 4) + i];
            k++;
        }
    }
    (void)unicycle_kern_node_predict(post_packed, u, Q, centre, x1, P1_packed);
    k = 0;
    for (j = 0; j < 4; j++) {
        for (i = 0; i <= j; i++) {
            P1[(j * 4) + i] = P1_packed[k];
            P1[(i * 4) + j] = P1_packed[k];
            k++;
        }
    }
    return 0;
}
