// What the OpenCV shims (src/cv/cvshim.cpp, src/slam/slamshim.cpp) share:
// the message out of a caught exception, the camera matrix of fx fy cx cy and
// the depth agreement of a relative pose.
#ifndef SOOC3D_CVMAT_HPP
#define SOOC3D_CVMAT_HPP

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <string>

#include <opencv2/core.hpp>

namespace sooc_cv {

inline void set_err(char *err, size_t cap, const std::string &msg) {
    if (err && cap) std::snprintf(err, cap, "%s", msg.c_str());
}

// K = fx fy cx cy
inline cv::Mat camera_matrix(const double K[4]) {
    cv::Mat m = cv::Mat::eye(3, 3, CV_64F);
    m.at<double>(0, 0) = K[0];
    m.at<double>(1, 1) = K[1];
    m.at<double>(0, 2) = K[2];
    m.at<double>(1, 2) = K[3];
    return m;
}

// Depth agreement of T (p_dst = T * p_src) between two depth images (CV_32F,
// metres) of one camera K: every step-th pixel of src with depth in
// (min_d, max_d) counts in n; moved by T and projected (nearest pixel) onto a
// dst pixel with depth in (min_d, max_d) it counts in inview, and in agree
// when the two depths differ by at most max_diff.
struct DepthAgreement {
    long n = 0, inview = 0, agree = 0;
};

inline DepthAgreement depth_agreement(const cv::Mat &src, const cv::Mat &dst, const double K[4], const double T[16],
                                      double min_d, double max_d, double max_diff, int step) {
    DepthAgreement a;
    const double fx = K[0], fy = K[1], cx = K[2], cy = K[3];
    for (int y = 0; y < src.rows; y += step)
        for (int x = 0; x < src.cols; x += step) {
            float z = src.at<float>(y, x);
            if (!(z > min_d && z < max_d)) continue;
            a.n++;
            double X = (x - cx) / fx * z, Y = (y - cy) / fy * z;
            double px = T[0] * X + T[1] * Y + T[2] * z + T[3];
            double py = T[4] * X + T[5] * Y + T[6] * z + T[7];
            double pz = T[8] * X + T[9] * Y + T[10] * z + T[11];
            if (pz <= 1e-6) continue;
            int u = (int)std::lround(fx * px / pz + cx), v = (int)std::lround(fy * py / pz + cy);
            if (u < 0 || v < 0 || u >= dst.cols || v >= dst.rows) continue;
            float zd = dst.at<float>(v, u);
            if (!(zd > min_d && zd < max_d)) continue;
            a.inview++;
            if (std::fabs(zd - pz) <= max_diff) a.agree++;
        }
    return a;
}

}  // namespace sooc_cv

#endif
