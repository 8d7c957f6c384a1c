// What the OpenCV shims (src/cv/cvshim.cpp, src/slam/slamshim.cpp) share:
// the message out of a caught exception and the camera matrix of fx fy cx cy.
#ifndef SOOC3D_CVMAT_HPP
#define SOOC3D_CVMAT_HPP

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

}  // namespace sooc_cv

#endif
