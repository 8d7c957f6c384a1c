/* Internals shared by the data module's files (not public API). */
#ifndef SOOC3D_DATA_IMPL_H
#define SOOC3D_DATA_IMPL_H

#include "sooc3d/core.h"

#include <string.h>

/* Write `buf` to "<path>.tmp" then rename it over `path` (no fsync): bulk
 * dataset files (frames, meshes, pictures). */
sooc_status sooc_data_write_file(const char *path, const void *buf, size_t n);

#endif
