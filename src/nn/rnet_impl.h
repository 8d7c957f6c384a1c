/* Private helpers of the refinement-network kernels (rconv.c, rcell.c). */
#ifndef SOOC3D_NN_RNET_IMPL_H
#define SOOC3D_NN_RNET_IMPL_H
#include "nn_impl.h"
#include "sooc3d/nn_kern.h"
#include "sooc3d/nn_refine.h"

/* y[j] = elu(y[j] + bias) over n values (the Cephes-polynomial ELU of nn_refine.h). */
void sooc_nn_r_elu_bias(float *y, int64_t n, float bias);
float sooc_nn_r_elu1(float x);
#endif
