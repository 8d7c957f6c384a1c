/* C interface of the SLAM module's C++ shim (slamshim.cpp): OpenCV ORB
 * features, PnP RANSAC, depth-only ICP refinement (contrib rgbd) and the
 * pose-graph optimisation with Ceres. Only src/slam calls it.
 *
 * Functions return 0 on success and a negative value on failure with a
 * message in err (errcap bytes); nothing prints or throws. Matrices are
 * row-major doubles; pixel (0, 0) has its centre at (0, 0) (OpenCV). */
#ifndef SOOC3D_SLAMSHIM_H
#define SOOC3D_SLAMSHIM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ORB keypoints of an 8-bit grey image: up to nmax, strongest first; uv: 2
 * floats per keypoint (pixels), desc: 32 bytes per keypoint. *n = count. */
int sooc_slsh_orb(const uint8_t *gray, int w, int h, int nmax, float *uv, uint8_t *desc, int *n, char *err,
                  size_t errcap);

/* solvePnPRansac (EPnP hypotheses, then iterative refinement on the
 * inliers) of n 3D points obj (3 doubles, the model's frame) seen at pixels
 * img (2 doubles) by a pinhole camera K = fx fy cx cy: T_cam_obj (p_cam =
 * T * p_obj), inl[i] = 1 for inliers (may be NULL), *ninl. Returns 1 when a
 * pose is found, 0 when RANSAC fails, < 0 on an error. */
int sooc_slsh_pnp_ransac(int n, const double *obj, const double *img, const double K[4], int iters,
                         double reproj_px, double T[16], uint8_t *inl, int *ninl, char *err, size_t errcap);

/* Depth-only ICP (cv::rgbd::ICPOdometry) between two depth images of one
 * camera (w x h, metres, 0 = invalid). */
typedef struct sooc_slsh_icp sooc_slsh_icp;
int sooc_slsh_icp_create(sooc_slsh_icp **out, const double K[4], int w, int h, double min_depth,
                         double max_depth, double max_depth_diff, char *err, size_t errcap);
void sooc_slsh_icp_destroy(sooc_slsh_icp *c);   /* NULL-safe */
/* T_dst_src (p_dst = T * p_src) from init. Of the source's valid pixels
 * (every 2nd), *overlap = the fraction that land on a valid destination
 * pixel, *agree = the fraction of those within max_depth_diff of its depth.
 * Returns 1 when ICP converged, 0 when it failed. */
int sooc_slsh_icp_run(sooc_slsh_icp *c, const float *src, const float *dst, const double init[16], double T[16],
                      double *agree, double *overlap, char *err, size_t errcap);

/* Pose-graph optimisation (Ceres, Levenberg-Marquardt, sparse normal
 * Cholesky). Nodes: nn camera-to-world poses T (16 doubles each, updated in
 * place); fixed[i] = 1 holds node i. Edges: ne pairs ij[2e], ij[2e+1] with
 * the measured relative pose Tij (16 each, T_i^-1 T_j), weights w[2e] (1 /
 * sigma of translation, metres) and w[2e+1] (1 / sigma of rotation,
 * radians); robust[e] = 1 puts a Huber loss (scale 1 in weighted units) on
 * the edge. Residual per edge (6): w_t (R_i^T (t_j - t_i) - t_ij) and
 * w_r 2 vec(q_ij^-1 q_i^-1 q_j). cost0/cost1: the cost before and after. */
int sooc_slsh_pgo(int nn, double *T, const uint8_t *fixed, int ne, const int *ij, const double *Tij,
                  const double *w, const uint8_t *robust, int max_iter, double *cost0, double *cost1, int *iters,
                  char *err, size_t errcap);

/* A pose as the optimiser's parameters: t (3) and the unit quaternion
 * (x y z w) of its rotation, and back. */
void sooc_slsh_T_to_tq(const double T[16], double t[3], double q[4]);
void sooc_slsh_tq_to_T(const double t[3], const double q[4], double T[16]);

/* The residual of one edge at node parameters (ti, qi), (tj, qj) (for the
 * derivative checks): r[6] as in sooc_slsh_pgo, and the 6 x 7 Jacobians
 * (Ceres automatic differentiation) with respect to node i's and node j's
 * parameters (t then quaternion x y z w, not normalised; may be NULL).
 * Returns 0, or -1 without Ceres. */
int sooc_slsh_pgo_residual(const double ti[3], const double qi[4], const double tj[3], const double qj[4],
                           const double Tij[16], const double w[2], double r[6], double *Ji, double *Jj);

/* 1 if the shim was built with Ceres. */
int sooc_slsh_have_ceres(void);

#ifdef __cplusplus
}
#endif
#endif
