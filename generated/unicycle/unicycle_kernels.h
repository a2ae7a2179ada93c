/* DO NOT EDIT: unicycle module, generated from template kernels.h.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build unicycle`. */
/* The typed entry points of the CasADi kernels that the library calls, generated from each
 * kernel's signature, and the work size each needs (none for the kernels that keep their work
 * in locals). The package installs this header beside the API's: the example program
 * simulates its plant with the mean map. Which kernels exist follows the build's options.
 * Inputs are const, outputs writable, arrays row-major with the sizes given; none may be NULL
 * and no output may overlap an input. */
#ifndef UNICYCLE_KERNELS_H
#define UNICYCLE_KERNELS_H

#include "unicycle.h"

/* unicycle_kern_node_predict:(post[14],u[2],Q[10],centre[2])->(x1[4],P1[10]) */
int unicycle_kern_node_predict(const unicycle_real post[14], const unicycle_real u[2],
                               const unicycle_real Q[10], const unicycle_real centre[2],
                               unicycle_real x1[4], unicycle_real P1[10]);

/* unicycle_kern_update:(prior[14],e[2],R[2x2])->(post[14],piv[2]) */
int unicycle_kern_update(const unicycle_real prior[14], const unicycle_real e[2],
                         const unicycle_real R[4], unicycle_real post[14], unicycle_real piv[2]);

/* unicycle_kern_info:(x[4],P[4x4],c[4])->(Y[4x4],y[4],piv[4]) */
int unicycle_kern_info(const unicycle_real x[4], const unicycle_real P[16],
                       const unicycle_real c[4], unicycle_real Y[16], unicycle_real y[4],
                       unicycle_real piv[4]);

/* unicycle_kern_node_predict_P:(P[10],Q[10])->(P1[10]) */
int unicycle_kern_node_predict_P(const unicycle_real P[10], const unicycle_real Q[10],
                                 unicycle_real P1[10]);

/* unicycle_kern_domain:(x[4])->(F[2],G[2x2]) */
int unicycle_kern_domain(const unicycle_real x[4], unicycle_real F[2], unicycle_real G[4]);

/* unicycle_kern_noise:(q[2])->(Q[10]) */
int unicycle_kern_noise(const unicycle_real q[2], unicycle_real Q[10]);

/* unicycle_kern_predict:(x[4],P[4x4],u[2],Q[10],centre[2])->(x1[4],P1[4x4]) */
int unicycle_kern_predict(const unicycle_real x[4], const unicycle_real P[16],
                          const unicycle_real u[2], const unicycle_real Q[10],
                          const unicycle_real centre[2], unicycle_real x1[4], unicycle_real P1[16]);

/* unicycle_kern_master_gain:(x[4],P[4x4],xp[4],Pp[4x4],c[4])->(dY[10],dy[4],piv[8]) */
int unicycle_kern_master_gain(const unicycle_real x[4], const unicycle_real P[16],
                              const unicycle_real xp[4], const unicycle_real Pp[16],
                              const unicycle_real c[4], unicycle_real dY[10], unicycle_real dy[4],
                              unicycle_real piv[8]);

/* unicycle_kern_fuse_finish:(Pc[4x4],dY[10],dy[4],c[4])->(x[4],P[4x4],piv[8]) */
int unicycle_kern_fuse_finish(const unicycle_real Pc[16], const unicycle_real dY[10],
                              const unicycle_real dy[4], const unicycle_real c[4],
                              unicycle_real x[4], unicycle_real P[16], unicycle_real piv[8]);

/* unicycle_kern_control:(x[4],flags[6],gains[4],params[0])->(u[2],v[2],det,nsat) */
#define UNICYCLE_KERN_CONTROL_SZ_W 24
int unicycle_kern_control(const unicycle_real x[4], const unicycle_real flags[6],
                          const unicycle_real gains[4], const unicycle_real params[1],
                          unicycle_real u[2], unicycle_real v[2], unicycle_real det[1],
                          unicycle_real nsat[1], unicycle_real w[UNICYCLE_KERN_CONTROL_SZ_W]);

#endif /* UNICYCLE_KERNELS_H */
