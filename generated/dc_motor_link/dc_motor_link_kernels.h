/* DO NOT EDIT: dc_motor_link module, generated from template kernels.h.j2 by dfeif-codegen
 * 0.1.0; regenerate with `codegen build dc_motor_link`. */
/* The typed entry points of the CasADi kernels that the library calls, generated from each
 * kernel's signature, and the work size each needs (none for the kernels that keep their work
 * in locals). The package installs this header beside the API's: the example program
 * simulates its plant with the mean map. Which kernels exist follows the build's options.
 * Inputs are const, outputs writable, arrays row-major with the sizes given; none may be NULL
 * and no output may overlap an input. */
#ifndef DC_MOTOR_LINK_KERNELS_H
#define DC_MOTOR_LINK_KERNELS_H

#include "dc_motor_link.h"

/* dc_motor_link_kern_node_predict:(post[9],u,Q[6],centre)->(x1[3],P1[6]) */
int dc_motor_link_kern_node_predict(const dc_motor_link_real post[9], const dc_motor_link_real u[1],
                                    const dc_motor_link_real Q[6],
                                    const dc_motor_link_real centre[1], dc_motor_link_real x1[3],
                                    dc_motor_link_real P1[6]);

/* dc_motor_link_kern_update:(prior[9],e,R)->(post[9],piv) */
int dc_motor_link_kern_update(const dc_motor_link_real prior[9], const dc_motor_link_real e[1],
                              const dc_motor_link_real R[1], dc_motor_link_real post[9],
                              dc_motor_link_real piv[1]);

/* dc_motor_link_kern_info:(x[3],P[3x3],c[3])->(Y[3x3],y[3],piv[3]) */
int dc_motor_link_kern_info(const dc_motor_link_real x[3], const dc_motor_link_real P[9],
                            const dc_motor_link_real c[3], dc_motor_link_real Y[9],
                            dc_motor_link_real y[3], dc_motor_link_real piv[3]);

/* dc_motor_link_kern_node_predict_P:(P[6],Q[6])->(P1[6]) */
int dc_motor_link_kern_node_predict_P(const dc_motor_link_real P[6], const dc_motor_link_real Q[6],
                                      dc_motor_link_real P1[6]);

/* dc_motor_link_kern_domain:(x[3])->(F,G) */
int dc_motor_link_kern_domain(const dc_motor_link_real x[3], dc_motor_link_real F[1],
                              dc_motor_link_real G[1]);

/* dc_motor_link_kern_noise:(q)->(Q[6]) */
int dc_motor_link_kern_noise(const dc_motor_link_real q[1], dc_motor_link_real Q[6]);

/* dc_motor_link_kern_predict:(x[3],P[3x3],u,Q[6],centre)->(x1[3],P1[3x3]) */
int dc_motor_link_kern_predict(const dc_motor_link_real x[3], const dc_motor_link_real P[9],
                               const dc_motor_link_real u[1], const dc_motor_link_real Q[6],
                               const dc_motor_link_real centre[1], dc_motor_link_real x1[3],
                               dc_motor_link_real P1[9]);

/* dc_motor_link_kern_master_gain:(x[3],P[3x3],xp[3],Pp[3x3],c[3])->(dY[6],dy[3],piv[6]) */
int dc_motor_link_kern_master_gain(const dc_motor_link_real x[3], const dc_motor_link_real P[9],
                                   const dc_motor_link_real xp[3], const dc_motor_link_real Pp[9],
                                   const dc_motor_link_real c[3], dc_motor_link_real dY[6],
                                   dc_motor_link_real dy[3], dc_motor_link_real piv[6]);

/* dc_motor_link_kern_fuse_finish:(Pc[3x3],dY[6],dy[3],c[3])->(x[3],P[3x3],piv[6]) */
int dc_motor_link_kern_fuse_finish(const dc_motor_link_real Pc[9], const dc_motor_link_real dY[6],
                                   const dc_motor_link_real dy[3], const dc_motor_link_real c[3],
                                   dc_motor_link_real x[3], dc_motor_link_real P[9],
                                   dc_motor_link_real piv[6]);

/* dc_motor_link_kern_control:(x[3],flags[4],gains[3],params[8])->(u,v,det,nsat) */
#define DC_MOTOR_LINK_KERN_CONTROL_SZ_W 27
int dc_motor_link_kern_control(const dc_motor_link_real x[3], const dc_motor_link_real flags[4],
                               const dc_motor_link_real gains[3],
                               const dc_motor_link_real params[8], dc_motor_link_real u[1],
                               dc_motor_link_real v[1], dc_motor_link_real det[1],
                               dc_motor_link_real nsat[1],
                               dc_motor_link_real w[DC_MOTOR_LINK_KERN_CONTROL_SZ_W]);

#endif /* DC_MOTOR_LINK_KERNELS_H */
