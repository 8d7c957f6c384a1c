/* Private helpers shared by the nn sources. */
#ifndef SOOC3D_NN_IMPL_H
#define SOOC3D_NN_IMPL_H
#include "sooc3d/nn.h"
#include <cblas.h>
#undef I /* complex.h (pulled in by OpenBLAS) defines I; we use it as a size */
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

/* Minimum elements before an elementwise loop goes parallel. */
#define SOOC_NN_PAR_MIN 32768

#endif
