/* Private parts of the frames-from-a-log reader (logseq.c): the TF buffer
 * and the image conversions. */
#ifndef SOOC3D_LOGSEQ_IMPL_H
#define SOOC3D_LOGSEQ_IMPL_H

#include "sooc3d/core.h"
#include "sooc3d/log.h"

/* ---- TF buffer (tf.c): each frame has one parent and a time series of its
 * pose in that parent; /tf_static edges hold at every time. */
typedef struct sooc_logs_tf sooc_logs_tf;
sooc_status sooc_logs_tf_create(sooc_logs_tf **out);
void sooc_logs_tf_free(sooc_logs_tf *tf);
/* Add one transform; a child already attached to another parent keeps the
 * first. */
sooc_status sooc_logs_tf_add(sooc_logs_tf *tf, const sooc_ros_transform *t, int is_static);
void sooc_logs_tf_finish(sooc_logs_tf *tf);   /* sort the samples; call once after the last add */
int64_t sooc_logs_tf_count(const sooc_logs_tf *tf);
int sooc_logs_tf_has_frame(const sooc_logs_tf *tf, const char *name);
/* "a, b, c" (at most cap bytes) for messages. */
void sooc_logs_tf_frame_list(const sooc_logs_tf *tf, char *buf, size_t cap);
/* T (row-major, p_parent = T p_child) at time t: interpolated between the
 * samples around t on every edge; outside an edge's samples the nearest one
 * serves when it is within tol_ns. ENOTFOUND naming the frames, the edge or
 * the time otherwise. */
sooc_status sooc_logs_tf_lookup(const sooc_logs_tf *tf, const char *parent, const char *child, int64_t t, int64_t tol_ns,
                           double T[16]);
/* The root of the tree that holds frame (frame itself when it has no
 * parent), NULL when the frame is not in the buffer. */
const char *sooc_logs_tf_root(const sooc_logs_tf *tf, const char *frame);

/* ---- images (logseq_img.c) ---- */
typedef enum sooc_logs_pix {
    LOGS_PIX_NONE = 0, LOGS_PIX_RGB8, LOGS_PIX_BGR8, LOGS_PIX_RGBA8, LOGS_PIX_BGRA8, LOGS_PIX_MONO8,
    LOGS_PIX_U16, LOGS_PIX_F32
} sooc_logs_pix;
/* An Image encoding: rgb8 bgr8 rgba8 bgra8 mono8 8UC1 8UC3 (bgr) 8UC4 (bgra), mono16 16UC1, 32FC1. */
sooc_logs_pix sooc_logs_pix_parse(const char *encoding);
int sooc_logs_pix_is_depth(sooc_logs_pix p);
/* Colour of an Image or CompressedImage into rgb (w x h x 3, the image's own
 * size, which must match). img is scratch for compressed data. */
sooc_status sooc_logs_color_image(const sooc_ros_image *im, uint8_t *rgb, int w, int h);
sooc_status sooc_logs_color_compressed(const sooc_ros_cimage *ci, sooc_image *img, const char *name);
/* Depth in metres (0 = invalid) at the image's own size into z (w x h). */
sooc_status sooc_logs_depth_image(const sooc_ros_image *im, double scale, float *z, int w, int h);
/* compressedDepth: the 12-byte configuration header then a PNG (16UC1 raw
 * units times scale, or 32FC1 quantised inverse depth). */
sooc_status sooc_logs_depth_compressed(const sooc_ros_cimage *ci, double scale, sooc_image *img, float **z, size_t *cap,
                                  int *w, int *h, const char *name);
/* Reproject depth (Kd, wd x hd) into the colour camera (Kc, wc x hc) with
 * p_color = T_cd p_depth; each depth pixel covers its footprint in the colour
 * image, the nearest surface wins. Pixel centres at integer coordinates
 * (ROS/OpenCV). out: wc x hc, overwritten. */
void sooc_logs_register_depth(const float *zd, const sooc_intrinsics *Kd, const double T_cd[16], float *out,
                         const sooc_intrinsics *Kc);

#endif
