/* Minimal C interface to OpenCV (src/cv/cvshim.cpp, C++): RGB-D odometry
 * from the contrib `rgbd` module, ChArUco/checkerboard detection (`aruco`,
 * `calib3d`), calibrateCamera, solvePnP and calibrateHandEye. Only
 * the C files of src/cv call it; the public API is include/sooc3d/slam.h.
 *
 * Functions return 0 on success and a negative value on failure with a
 * message in err (errcap bytes); no function prints or throws (OpenCV
 * exceptions are caught and turned into messages). Matrices are row-major
 * doubles. Pixel coordinates follow OpenCV: pixel (0, 0) has its centre at
 * (0, 0). */
#ifndef SOOC3D_CVSHIM_H
#define SOOC3D_CVSHIM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------- odometry */

typedef struct sooc_cvodo sooc_cvodo;

/* variant: 0 RGB-D (photometric), 1 ICP (depth only), 2 RGB-D + ICP.
 * K = fx fy cx cy at the working resolution w x h (the depth camera's).
 * Kc: the colour camera's intrinsics at the working resolution when colour
 * is not registered to depth, with p_color = T_cd * p_depth (T_cd may be
 * NULL: identity); Kc NULL = colour registered (same pixels as depth). */
int sooc_cvodo_create(sooc_cvodo **out, int variant, const double K[4], int w, int h, double min_depth,
                      double max_depth, double max_depth_diff, double max_points_part, double max_translation,
                      double max_rotation_deg, const double Kc[4], const double T_cd[16], char *err,
                      size_t errcap);
void sooc_cvodo_destroy(sooc_cvodo *o);   /* NULL-safe */
/* Load the current frame: RGB8 (sw x sh) and depth in metres (0 = invalid),
 * resized to the working resolution (area for the image, nearest for depth).
 * With a colour camera (Kc), the grey image is resampled into the depth
 * camera: each depth pixel takes the colour at its point's projection
 * (pixels without depth: the projection of their ray at infinity). */
int sooc_cvodo_load(sooc_cvodo *o, const uint8_t *rgb, const float *depth, int sw, int sh, char *err,
                    size_t errcap);
/* Make the loaded frame the keyframe (its pyramids are cached). */
int sooc_cvodo_set_keyframe(sooc_cvodo *o, char *err, size_t errcap);
/* Motion of the loaded frame relative to the keyframe: T_kf_cur (p_kf =
 * T * p_cur), starting from init (may be NULL). Returns 1 when OpenCV reports
 * success (enough correspondences, motion within the bounds), 0 when it
 * fails, < 0 on an error. */
int sooc_cvodo_track(sooc_cvodo *o, const double init[16], double T_kf_cur[16], char *err, size_t errcap);

/* Geometric check of a result: the loaded frame's valid depth pixels
 * (every `step`-th) are moved by T_kf_cur into the keyframe; *agree = the
 * fraction of them that land on a valid keyframe depth within max_diff
 * metres (z in the keyframe's camera). */
int sooc_cvodo_check(sooc_cvodo *o, const double T_kf_cur[16], double max_diff, int step, double *agree,
                     char *err, size_t errcap);

/* The loaded frame at the working resolution, in the depth camera: grey
 * (8-bit, w x h; the colour resampled into the depth camera when it is not
 * registered) and depth (metres, 0 = invalid). Either output may be NULL
 * (only *w, *h and K). Returns 1 when the frame has no grey image (ICP
 * variant), 0 on success, < 0 when no frame is loaded. K = fx fy cx cy. */
int sooc_cvodo_current(const sooc_cvodo *o, uint8_t *gray, float *depth, int *w, int *h, double K[4], char *err,
                       size_t errcap);

/* ----------------------------------------------------------- calibration */

typedef struct sooc_cvboard sooc_cvboard;

/* kind 0 ChArUco (dict = cv::aruco::PREDEFINED_DICTIONARY_NAME), 1
 * checkerboard (sx x sy squares, (sx-1) x (sy-1) inner corners). */
int sooc_cvboard_create(sooc_cvboard **out, int kind, int sx, int sy, double square, double marker, int dict,
                        char *err, size_t errcap);
void sooc_cvboard_destroy(sooc_cvboard *b);
/* Number of corner points a full detection has. */
int sooc_cvboard_npoints(const sooc_cvboard *b);
/* Draw the flat board (8-bit gray, w x h, no margin). */
int sooc_cvboard_draw(const sooc_cvboard *b, uint8_t *gray, int w, int h, char *err, size_t errcap);
/* Detect the board in an 8-bit gray image: up to cap corners as board
 * coordinates (obj, 3 per point, metres, z = 0) and pixels (img, 2 per
 * point, sub-pixel). *n = 0 when no board is found. */
int sooc_cvboard_detect(const sooc_cvboard *b, const uint8_t *gray, int w, int h, double *obj, double *img,
                        int cap, int *n, char *err, size_t errcap);

/* calibrateCamera over nv views; view v has counts[v] points, stored one
 * after another in obj (3 per point) and img (2 per point). dist_n: number
 * of distortion coefficients to estimate (0, 4 or 5; 0 fixes them at 0).
 * Outputs K (fx fy cx cy), dist[5], the RMS reprojection error, and per view
 * the board pose T_cam_board (16 doubles per view; may be NULL). */
int sooc_cv_calibrate(int nv, const int *counts, const double *obj, const double *img, int w, int h, int dist_n,
                      double K[4], double dist[5], double *rms, double *T_cam_board, char *err, size_t errcap);
/* solvePnP (iterative) of one view with known K (fx fy cx cy) and dist[5];
 * returns T_cam_board and the RMS reprojection error in pixels. */
int sooc_cv_pnp(int n, const double *obj, const double *img, const double K[4], const double dist[5],
                double T_cam_board[16], double *rms, char *err, size_t errcap);
/* calibrateHandEye (Tsai, Park, Horaud, Andreff or Daniilidis = method 0..4)
 * with n pairs T_base_ee[i] and T_cam_board[i] (16 doubles each) -> T_ee_cam. */
int sooc_cv_handeye(int n, const double *T_base_ee, const double *T_cam_board, int method, double T_ee_cam[16],
                    char *err, size_t errcap);

/* Read a calibration YAML with OpenCV's FileStorage (the check that files
 * the node reads also load in OpenCV): image_width/height and
 * camera_matrix (ROS {rows, cols, data} or !!opencv-matrix). */
int sooc_cv_yaml_read(const char *path, int *w, int *h, double K[9], char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif
