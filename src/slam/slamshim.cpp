// OpenCV and Ceres behind the C interface of slamshim.h: ORB features,
// PnP RANSAC, depth-only ICP and the pose-graph optimisation. Every entry
// point catches exceptions and returns a message.
#include "slamshim.h"
#include "cv/cvmat.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/rgbd.hpp>

#if SOOC_HAVE_CERES
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <ceres/ceres.h>
#endif

using sooc_cv::camera_matrix;
using sooc_cv::set_err;

extern "C" int sooc_slsh_orb(const uint8_t *gray, int w, int h, int nmax, float *uv, uint8_t *desc, int *n,
                             char *err, size_t errcap) {
    *n = 0;
    try {
        cv::Mat img(h, w, CV_8UC1, const_cast<uint8_t *>(gray));
        // 4 levels x 1.2: small working images; FAST threshold 12 for low-contrast rooms
        auto orb = cv::ORB::create(nmax, 1.2f, 4, 15, 0, 2, cv::ORB::HARRIS_SCORE, 31, 12);
        std::vector<cv::KeyPoint> kp;
        cv::Mat d;
        orb->detectAndCompute(img, cv::noArray(), kp, d);
        int m = (int)kp.size();
        if (m > nmax) m = nmax;
        for (int i = 0; i < m; i++) {
            uv[2 * i] = kp[i].pt.x;
            uv[2 * i + 1] = kp[i].pt.y;
            std::memcpy(desc + 32 * (size_t)i, d.ptr<uint8_t>(i), 32);
        }
        *n = m;
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV ORB: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_slsh_pnp_ransac(int n, const double *obj, const double *img, const double K[4], int iters,
                                    double reproj_px, double T[16], uint8_t *inl, int *ninl, char *err,
                                    size_t errcap) {
    *ninl = 0;
    if (inl) std::memset(inl, 0, (size_t)(n > 0 ? n : 0));
    if (n < 6) return 0;
    try {
        std::vector<cv::Point3d> o((size_t)n);
        std::vector<cv::Point2d> p((size_t)n);
        for (int i = 0; i < n; i++) {
            o[i] = cv::Point3d(obj[3 * i], obj[3 * i + 1], obj[3 * i + 2]);
            p[i] = cv::Point2d(img[2 * i], img[2 * i + 1]);
        }
        cv::Mat rvec, tvec;
        std::vector<int> in;
        bool ok = cv::solvePnPRansac(o, p, camera_matrix(K), cv::Mat(), rvec, tvec, false, iters, (float)reproj_px,
                                     0.999, in, cv::SOLVEPNP_EPNP);
        if (!ok || (int)in.size() < 6) return 0;
        // refine on the inliers
        std::vector<cv::Point3d> oi;
        std::vector<cv::Point2d> pi;
        for (int k : in) {
            oi.push_back(o[k]);
            pi.push_back(p[k]);
        }
        cv::solvePnP(oi, pi, camera_matrix(K), cv::Mat(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
        cv::Mat R;
        cv::Rodrigues(rvec, R);
        for (int r = 0; r < 3; r++) {
            for (int c = 0; c < 3; c++) T[r * 4 + c] = R.at<double>(r, c);
            T[r * 4 + 3] = tvec.at<double>(r);
        }
        T[12] = T[13] = T[14] = 0;
        T[15] = 1;
        for (int i = 0; i < 12; i++)
            if (!std::isfinite(T[i])) return 0;
        // inliers after the refinement
        const double fx = K[0], fy = K[1], cx = K[2], cy = K[3], r2 = reproj_px * reproj_px;
        int m = 0;
        for (int i = 0; i < n; i++) {
            const double *X = obj + 3 * i;
            double x = T[0] * X[0] + T[1] * X[1] + T[2] * X[2] + T[3];
            double y = T[4] * X[0] + T[5] * X[1] + T[6] * X[2] + T[7];
            double z = T[8] * X[0] + T[9] * X[1] + T[10] * X[2] + T[11];
            if (z <= 1e-6) continue;
            double du = fx * x / z + cx - img[2 * i], dv = fy * y / z + cy - img[2 * i + 1];
            if (du * du + dv * dv <= r2) {
                m++;
                if (inl) inl[i] = 1;
            }
        }
        *ninl = m;
        return 1;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV solvePnPRansac: ") + e.what());
        return -1;
    }
}

struct sooc_slsh_icp {
    cv::Ptr<cv::rgbd::ICPOdometry> odo;
    int w = 0, h = 0;
    double K[4] = {0, 0, 0, 0}, min_depth = 0, max_depth = 0, max_diff = 0;
};

extern "C" int sooc_slsh_icp_create(sooc_slsh_icp **out, const double K[4], int w, int h, double min_depth,
                                    double max_depth, double max_depth_diff, char *err, size_t errcap) {
    *out = nullptr;
    try {
        auto c = std::make_unique<sooc_slsh_icp>();
        cv::Mat cam = camera_matrix(K);
        cam.convertTo(cam, CV_32F);
        // three pyramid levels: small (keyframe-sized) depth images
        std::vector<int> iters = {10, 5, 4};
        c->odo = cv::rgbd::ICPOdometry::create(cam, (float)min_depth, (float)max_depth, (float)max_depth_diff,
                                               0.5f, iters);
        c->odo->setMaxTranslation(0.5);
        c->odo->setMaxRotation(30);
        c->w = w;
        c->h = h;
        for (int i = 0; i < 4; i++) c->K[i] = K[i];
        c->min_depth = min_depth;
        c->max_depth = max_depth;
        c->max_diff = max_depth_diff;
        *out = c.release();
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV ICP: ") + e.what());
        return -1;
    }
}

extern "C" void sooc_slsh_icp_destroy(sooc_slsh_icp *c) { delete c; }

extern "C" int sooc_slsh_icp_run(sooc_slsh_icp *c, const float *src, const float *dst, const double init[16],
                                 double T[16], double *agree, double *overlap, char *err, size_t errcap) {
    *agree = *overlap = 0;
    try {
        cv::Mat ds = cv::Mat(c->h, c->w, CV_32F, const_cast<float *>(src)).clone();
        cv::Mat dd = cv::Mat(c->h, c->w, CV_32F, const_cast<float *>(dst)).clone();
        auto fs = cv::rgbd::OdometryFrame::create(cv::Mat(), ds);
        auto fd = cv::rgbd::OdometryFrame::create(cv::Mat(), dd);
        cv::Mat initRt(4, 4, CV_64F), Rt;
        for (int i = 0; i < 16; i++) initRt.at<double>(i / 4, i % 4) = init[i];
        bool ok = c->odo->compute(fs, fd, Rt, initRt);
        if (!ok || Rt.empty()) return 0;
        cv::Mat R64;
        Rt.convertTo(R64, CV_64F);
        for (int i = 0; i < 16; i++) T[i] = R64.at<double>(i / 4, i % 4);
        for (int i = 0; i < 16; i++)
            if (!std::isfinite(T[i])) return 0;
        /* on the caller's depth, as given (the frames above are OpenCV's) */
        const cv::Mat s0(c->h, c->w, CV_32F, const_cast<float *>(src)), d0(c->h, c->w, CV_32F, const_cast<float *>(dst));
        sooc_cv::DepthAgreement a = sooc_cv::depth_agreement(s0, d0, c->K, T, c->min_depth, c->max_depth, c->max_diff, 2);
        *agree = a.inview ? (double)a.agree / (double)a.inview : 0;
        *overlap = a.n ? (double)a.inview / (double)a.n : 0;
        return 1;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV ICP: ") + e.what());
        return -1;
    }
}

// ------------------------------------------------------------ pose graph

#if SOOC_HAVE_CERES
namespace {

struct EdgeCost {
    Eigen::Vector3d t_m;
    Eigen::Quaterniond q_m;
    double wt, wr;
    template <typename S>
    bool operator()(const S *ti, const S *qi, const S *tj, const S *qj, S *r) const {
        Eigen::Map<const Eigen::Matrix<S, 3, 1>> pi(ti), pj(tj);
        Eigen::Map<const Eigen::Quaternion<S>> Qi(qi), Qj(qj);
        Eigen::Quaternion<S> Qi_inv = Qi.conjugate();
        Eigen::Matrix<S, 3, 1> t_ij = Qi_inv * (pj - pi);
        Eigen::Quaternion<S> q_ij = Qi_inv * Qj;
        Eigen::Quaternion<S> dq = q_m.conjugate().template cast<S>() * q_ij;
        for (int k = 0; k < 3; k++) r[k] = S(wt) * (t_ij[k] - S(t_m[k]));
        // the same rotation error for q and -q: flip to w >= 0
        S sgn = dq.w() < S(0) ? S(-1) : S(1);
        r[3] = S(wr) * S(2) * sgn * dq.x();
        r[4] = S(wr) * S(2) * sgn * dq.y();
        r[5] = S(wr) * S(2) * sgn * dq.z();
        return true;
    }
};

void T_to_tq(const double T[16], double t[3], double q[4]) {
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) R(r, c) = T[r * 4 + c];
    Eigen::Quaterniond Q(R);
    Q.normalize();
    q[0] = Q.x();
    q[1] = Q.y();
    q[2] = Q.z();
    q[3] = Q.w();
    t[0] = T[3];
    t[1] = T[7];
    t[2] = T[11];
}

void tq_to_T(const double t[3], const double q[4], double T[16]) {
    Eigen::Quaterniond Q(q[3], q[0], q[1], q[2]);
    Q.normalize();
    Eigen::Matrix3d R = Q.toRotationMatrix();
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) T[r * 4 + c] = R(r, c);
        T[r * 4 + 3] = t[r];
    }
    T[12] = T[13] = T[14] = 0;
    T[15] = 1;
}

ceres::CostFunction *make_cost(const double Tij[16], double wt, double wr) {
    double t[3], q[4];
    T_to_tq(Tij, t, q);
    auto *e = new EdgeCost{Eigen::Vector3d(t[0], t[1], t[2]), Eigen::Quaterniond(q[3], q[0], q[1], q[2]), wt, wr};
    return new ceres::AutoDiffCostFunction<EdgeCost, 6, 3, 4, 3, 4>(e);
}

}  // namespace
#endif

extern "C" int sooc_slsh_have_ceres(void) {
#if SOOC_HAVE_CERES
    return 1;
#else
    return 0;
#endif
}

extern "C" int sooc_slsh_pgo(int nn, double *T, const uint8_t *fixed, int ne, const int *ij, const double *Tij,
                             const double *w, const uint8_t *robust, int max_iter, double *cost0, double *cost1,
                             int *iters, char *err, size_t errcap) {
    *cost0 = *cost1 = 0;
    *iters = 0;
#if !SOOC_HAVE_CERES
    (void)nn; (void)T; (void)fixed; (void)ne; (void)ij; (void)Tij; (void)w; (void)robust; (void)max_iter;
    set_err(err, errcap, "pose graph: built without Ceres (libceres-dev)");
    return -1;
#else
    try {
        std::vector<double> t(3 * (size_t)nn), q(4 * (size_t)nn);
        for (int i = 0; i < nn; i++) T_to_tq(T + 16 * (size_t)i, &t[3 * (size_t)i], &q[4 * (size_t)i]);
        ceres::Problem problem;
        for (int e = 0; e < ne; e++) {
            int a = ij[2 * e], b = ij[2 * e + 1];
            if (a < 0 || b < 0 || a >= nn || b >= nn || a == b) {
                set_err(err, errcap, "pose graph: edge " + std::to_string(e) + " has bad nodes");
                return -1;
            }
            ceres::LossFunction *loss = robust && robust[e] ? new ceres::HuberLoss(1.0) : nullptr;
            problem.AddResidualBlock(make_cost(Tij + 16 * (size_t)e, w[2 * e], w[2 * e + 1]), loss, &t[3 * (size_t)a],
                                     &q[4 * (size_t)a], &t[3 * (size_t)b], &q[4 * (size_t)b]);
        }
        for (int i = 0; i < nn; i++) {
            if (!problem.HasParameterBlock(&q[4 * (size_t)i])) continue;
            problem.SetManifold(&q[4 * (size_t)i], new ceres::EigenQuaternionManifold);
            if (fixed && fixed[i]) {
                problem.SetParameterBlockConstant(&t[3 * (size_t)i]);
                problem.SetParameterBlockConstant(&q[4 * (size_t)i]);
            }
        }
        ceres::Solver::Options opt;
        opt.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
        opt.max_num_iterations = max_iter;
        opt.num_threads = 1;
        opt.logging_type = ceres::SILENT;
        opt.minimizer_progress_to_stdout = false;
        ceres::Solver::Summary sum;
        ceres::Solve(opt, &problem, &sum);
        *cost0 = sum.initial_cost;
        *cost1 = sum.final_cost;
        *iters = (int)sum.iterations.size();
        if (sum.termination_type == ceres::FAILURE || !std::isfinite(sum.final_cost)) {
            set_err(err, errcap, "pose graph: Ceres failed: " + sum.message);
            return -1;
        }
        for (int i = 0; i < nn; i++) tq_to_T(&t[3 * (size_t)i], &q[4 * (size_t)i], T + 16 * (size_t)i);
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("pose graph: ") + e.what());
        return -1;
    }
#endif
}

extern "C" void sooc_slsh_T_to_tq(const double T[16], double t[3], double q[4]) {
#if SOOC_HAVE_CERES
    T_to_tq(T, t, q);
#else
    (void)T; (void)t; (void)q;
#endif
}

extern "C" void sooc_slsh_tq_to_T(const double t[3], const double q[4], double T[16]) {
#if SOOC_HAVE_CERES
    tq_to_T(t, q, T);
#else
    (void)t; (void)q; (void)T;
#endif
}

extern "C" int sooc_slsh_pgo_residual(const double ti[3], const double qi[4], const double tj[3],
                                      const double qj[4], const double Tij[16], const double w[2], double r[6],
                                      double *Ji, double *Jj) {
#if !SOOC_HAVE_CERES
    (void)ti; (void)qi; (void)tj; (void)qj; (void)Tij; (void)w; (void)r; (void)Ji; (void)Jj;
    return -1;
#else
    std::unique_ptr<ceres::CostFunction> cf(make_cost(Tij, w[0], w[1]));
    const double *params[4] = {ti, qi, tj, qj};
    double jt_i[18], jq_i[24], jt_j[18], jq_j[24];
    double *jac[4] = {jt_i, jq_i, jt_j, jq_j};
    if (!cf->Evaluate(params, r, (Ji || Jj) ? jac : nullptr)) return -1;
    for (int k = 0; k < 6; k++)
        for (int c = 0; c < 7; c++) {
            if (Ji) Ji[k * 7 + c] = c < 3 ? jt_i[k * 3 + c] : jq_i[k * 4 + c - 3];
            if (Jj) Jj[k * 7 + c] = c < 3 ? jt_j[k * 3 + c] : jq_j[k * 4 + c - 3];
        }
    return 0;
#endif
}
