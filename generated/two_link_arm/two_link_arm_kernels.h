/* DO NOT EDIT: two_link_arm module, generated from template kernels.h.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build two_link_arm`. */
/* The typed entry points of the CasADi kernels that the library calls, generated from each
 * kernel's signature, and the work size each needs (none for the kernels that keep their work
 * in locals). The package installs this header beside the API's: the example program
 * simulates its plant with the mean map. Which kernels exist follows the build's options.
 * Inputs are const, outputs writable, arrays row-major with the sizes given; none may be NULL
 * and no output may overlap an input. */
#ifndef TWO_LINK_ARM_KERNELS_H
#define TWO_LINK_ARM_KERNELS_H

#include "two_link_arm.h"

/* two_link_arm_kern_node_predict:(post[27],u[2],Q[21],centre[2])->(x1[6],P1[21]) */
int two_link_arm_kern_node_predict(const two_link_arm_real post[27], const two_link_arm_real u[2],
                                   const two_link_arm_real Q[21], const two_link_arm_real centre[2],
                                   two_link_arm_real x1[6], two_link_arm_real P1[21]);

/* two_link_arm_kern_update:(prior[27],e[2],R[2x2])->(post[27],piv[2]) */
int two_link_arm_kern_update(const two_link_arm_real prior[27], const two_link_arm_real e[2],
                             const two_link_arm_real R[4], two_link_arm_real post[27],
                             two_link_arm_real piv[2]);

/* two_link_arm_kern_info:(x[6],P[6x6],c[6])->(Y[6x6],y[6],piv[6]) */
int two_link_arm_kern_info(const two_link_arm_real x[6], const two_link_arm_real P[36],
                           const two_link_arm_real c[6], two_link_arm_real Y[36],
                           two_link_arm_real y[6], two_link_arm_real piv[6]);

/* two_link_arm_kern_node_predict_P:(P[21],Q[21])->(P1[21]) */
int two_link_arm_kern_node_predict_P(const two_link_arm_real P[21], const two_link_arm_real Q[21],
                                     two_link_arm_real P1[21]);

/* two_link_arm_kern_domain:(x[6])->(F[2],G[2x2]) */
int two_link_arm_kern_domain(const two_link_arm_real x[6], two_link_arm_real F[2],
                             two_link_arm_real G[4]);

/* two_link_arm_kern_noise:(q[2])->(Q[21]) */
int two_link_arm_kern_noise(const two_link_arm_real q[2], two_link_arm_real Q[21]);

/* two_link_arm_kern_predict:(x[6],P[6x6],u[2],Q[21],centre[2])->(x1[6],P1[6x6]) */
int two_link_arm_kern_predict(const two_link_arm_real x[6], const two_link_arm_real P[36],
                              const two_link_arm_real u[2], const two_link_arm_real Q[21],
                              const two_link_arm_real centre[2], two_link_arm_real x1[6],
                              two_link_arm_real P1[36]);

/* two_link_arm_kern_master_gain:(x[6],P[6x6],xp[6],Pp[6x6],c[6])->(dY[21],dy[6],piv[12]) */
int two_link_arm_kern_master_gain(const two_link_arm_real x[6], const two_link_arm_real P[36],
                                  const two_link_arm_real xp[6], const two_link_arm_real Pp[36],
                                  const two_link_arm_real c[6], two_link_arm_real dY[21],
                                  two_link_arm_real dy[6], two_link_arm_real piv[12]);

/* two_link_arm_kern_fuse_finish:(Pc[6x6],dY[21],dy[6],c[6])->(x[6],P[6x6],piv[12]) */
int two_link_arm_kern_fuse_finish(const two_link_arm_real Pc[36], const two_link_arm_real dY[21],
                                  const two_link_arm_real dy[6], const two_link_arm_real c[6],
                                  two_link_arm_real x[6], two_link_arm_real P[36],
                                  two_link_arm_real piv[12]);

/* two_link_arm_kern_control:(x[6],flags[8],gains[6],params[11])->(u[2],v[2],det,nsat) */
#define TWO_LINK_ARM_KERN_CONTROL_SZ_W 95
int two_link_arm_kern_control(const two_link_arm_real x[6], const two_link_arm_real flags[8],
                              const two_link_arm_real gains[6], const two_link_arm_real params[11],
                              two_link_arm_real u[2], two_link_arm_real v[2],
                              two_link_arm_real det[1], two_link_arm_real nsat[1],
                              two_link_arm_real w[TWO_LINK_ARM_KERN_CONTROL_SZ_W]);

#endif /* TWO_LINK_ARM_KERNELS_H */
