/* DO NOT EDIT: pvtol module, generated from template kernels.h.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/* The typed entry points of the CasADi kernels that the library calls, generated from each
 * kernel's signature, and the work size each needs (none for the kernels that keep their work
 * in locals). The package installs this header beside the API's: the example program
 * simulates its plant with the mean map. Which kernels exist follows the build's options.
 * Inputs are const, outputs writable, arrays row-major with the sizes given; none may be NULL
 * and no output may overlap an input. */
#ifndef PVTOL_KERNELS_H
#define PVTOL_KERNELS_H

#include "pvtol.h"

/* pvtol_kern_node_predict:(post[44],u[2],Q[36],centre[2])->(x1[8],P1[36]) */
int pvtol_kern_node_predict(const pvtol_real post[44], const pvtol_real u[2],
                            const pvtol_real Q[36], const pvtol_real centre[2], pvtol_real x1[8],
                            pvtol_real P1[36]);

/* pvtol_kern_update:(prior[44],e[2],R[2x2])->(post[44],piv[2]) */
int pvtol_kern_update(const pvtol_real prior[44], const pvtol_real e[2], const pvtol_real R[4],
                      pvtol_real post[44], pvtol_real piv[2]);

/* pvtol_kern_node_predict_P:(P[36],Q[36])->(P1[36]) */
int pvtol_kern_node_predict_P(const pvtol_real P[36], const pvtol_real Q[36], pvtol_real P1[36]);

/* pvtol_kern_domain:(x[8])->(F[2],G[2x2]) */
int pvtol_kern_domain(const pvtol_real x[8], pvtol_real F[2], pvtol_real G[4]);

/* pvtol_kern_noise:(q[2])->(Q[36]) */
int pvtol_kern_noise(const pvtol_real q[2], pvtol_real Q[36]);

/* pvtol_kern_info:(x[8],P[8x8],c[8])->(Y[8x8],y[8],piv[8]) */
int pvtol_kern_info(const pvtol_real x[8], const pvtol_real P[64], const pvtol_real c[8],
                    pvtol_real Y[64], pvtol_real y[8], pvtol_real piv[8]);

/* pvtol_kern_predict:(x[8],P[8x8],u[2],Q[36],centre[2])->(x1[8],P1[8x8]) */
int pvtol_kern_predict(const pvtol_real x[8], const pvtol_real P[64], const pvtol_real u[2],
                       const pvtol_real Q[36], const pvtol_real centre[2], pvtol_real x1[8],
                       pvtol_real P1[64]);

/* pvtol_kern_master_gain:(x[8],P[8x8],xp[8],Pp[8x8],c[8])->(dY[36],dy[8],piv[16]) */
int pvtol_kern_master_gain(const pvtol_real x[8], const pvtol_real P[64], const pvtol_real xp[8],
                           const pvtol_real Pp[64], const pvtol_real c[8], pvtol_real dY[36],
                           pvtol_real dy[8], pvtol_real piv[16]);

/* pvtol_kern_fuse_finish:(Pc[8x8],dY[36],dy[8],c[8])->(x[8],P[8x8],piv[16]) */
int pvtol_kern_fuse_finish(const pvtol_real Pc[64], const pvtol_real dY[36], const pvtol_real dy[8],
                           const pvtol_real c[8], pvtol_real x[8], pvtol_real P[64],
                           pvtol_real piv[16]);

/* pvtol_kern_control:(x[8],flags[10],gains[8],params[3])->(u[2],v[2],det,nsat) */
#define PVTOL_KERN_CONTROL_SZ_W 38
int pvtol_kern_control(const pvtol_real x[8], const pvtol_real flags[10], const pvtol_real gains[8],
                       const pvtol_real params[3], pvtol_real u[2], pvtol_real v[2],
                       pvtol_real det[1], pvtol_real nsat[1],
                       pvtol_real w[PVTOL_KERN_CONTROL_SZ_W]);

#endif /* PVTOL_KERNELS_H */
