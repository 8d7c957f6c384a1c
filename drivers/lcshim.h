/* Minimal C interface to libcamera (drivers/lcshim.cpp, the project's only
 * C++). Functions return 0 on success, a negative value on failure with a
 * message in err (errcap bytes). Frames arrive on libcamera's thread through
 * the callback; copy the data out before returning. */
#ifndef SOOC3D_LCSHIM_H
#define SOOC3D_LCSHIM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_lc sooc_lc;
typedef void (*sooc_lc_frame_cb)(void *user, const uint8_t *data, size_t len, int w, int h, int stride,
                                 uint32_t fourcc, int64_t ts_ns, uint32_t seq);

/* Open camera `which` (decimal index or libcamera id) configured for about
 * w x h (0 = default) in a packed RGB/BGR/YUYV format. */
int sooc_lc_open(sooc_lc **out, const char *which, int w, int h, sooc_lc_frame_cb cb, void *user, char *err,
                 size_t errcap);
/* The configured format (after validation). fourcc is libcamera/DRM's. */
void sooc_lc_format(const sooc_lc *c, int *w, int *h, int *stride, uint32_t *fourcc, char *id, size_t idcap);
int sooc_lc_start(sooc_lc *c, char *err, size_t errcap);
void sooc_lc_stop(sooc_lc *c);
void sooc_lc_close(sooc_lc *c);   /* NULL-safe */

#ifdef __cplusplus
}
#endif
#endif
