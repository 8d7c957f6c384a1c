/* Private helpers of the refinement-network kernels (rconv.c, rcell.c). */
#ifndef SOOC3D_NN_RNET_IMPL_H
#define SOOC3D_NN_RNET_IMPL_H
#include "nn_impl.h"
#include "nn/nn_kern.h"
#include "nn/nn_refine.h"

float sooc_nn_r_elu1(float x);
#endif
