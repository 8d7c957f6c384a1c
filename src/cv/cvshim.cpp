// OpenCV behind a C interface (cvshim.h): rgbd odometry, ChArUco and
// checkerboard detection, calibrateCamera, solvePnP, calibrateHandEye.
// Every entry point catches OpenCV's exceptions and returns a message.
#include "cvshim.h"
#include "cv/cvmat.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>

namespace {

using sooc_cv::camera_matrix;
using sooc_cv::set_err;

cv::Mat to_mat44(const double T[16]) {
    cv::Mat m(4, 4, CV_64F);
    for (int i = 0; i < 16; i++) m.at<double>(i / 4, i % 4) = T[i];
    return m;
}

void from_mat44(const cv::Mat &m, double T[16]) {
    cv::Mat d;
    m.convertTo(d, CV_64F);
    for (int i = 0; i < 16; i++) T[i] = d.at<double>(i / 4, i % 4);
}

void rt_to_T(const cv::Mat &R, const cv::Mat &t, double T[16]) {
    cv::Mat Rd, td;
    R.convertTo(Rd, CV_64F);
    t.convertTo(td, CV_64F);
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) T[r * 4 + c] = Rd.at<double>(r, c);
        T[r * 4 + 3] = td.at<double>(r);
    }
    T[12] = T[13] = T[14] = 0;
    T[15] = 1;
}

void rvec_to_T(const cv::Mat &rvec, const cv::Mat &tvec, double T[16]) {
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    rt_to_T(R, tvec, T);
}

}  // namespace

// --------------------------------------------------------------- odometry

struct sooc_cvodo {
    cv::Ptr<cv::rgbd::Odometry> odo;
    int w = 0, h = 0, variant = 0;
    double K[4] = {0, 0, 0, 0}, min_depth = 0, max_depth = 0;
    bool unregistered = false;                 // colour camera != depth camera
    double Kc[4] = {0, 0, 0, 0}, Tcd[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    cv::Mat rgb_full, gray_full, gray, depth;   // reused buffers
    cv::Mat mapx, mapy;                         // colour-to-depth resampling maps (reused)
    cv::Ptr<cv::rgbd::OdometryFrame> cur, kf;
};

extern "C" int sooc_cvodo_create(sooc_cvodo **out, int variant, const double K[4], int w, int h, double min_depth,
                                 double max_depth, double max_depth_diff, double max_points_part,
                                 double max_translation, double max_rotation_deg, const double Kc[4],
                                 const double T_cd[16], char *err, size_t errcap) {
    *out = nullptr;
    try {
        auto *o = new sooc_cvodo();
        cv::Mat cam = camera_matrix(K);
        cam.convertTo(cam, CV_32F);
        if (variant == 0) {
            auto r = cv::rgbd::RgbdOdometry::create(cam, (float)min_depth, (float)max_depth, (float)max_depth_diff,
                                                    std::vector<int>(), std::vector<float>(),
                                                    (float)max_points_part);
            r->setMaxTranslation(max_translation);
            r->setMaxRotation(max_rotation_deg);
            o->odo = r;
        } else if (variant == 1) {
            auto r = cv::rgbd::ICPOdometry::create(cam, (float)min_depth, (float)max_depth, (float)max_depth_diff,
                                                   (float)max_points_part);
            r->setMaxTranslation(max_translation);
            r->setMaxRotation(max_rotation_deg);
            o->odo = r;
        } else {
            auto r = cv::rgbd::RgbdICPOdometry::create(cam, (float)min_depth, (float)max_depth,
                                                       (float)max_depth_diff, (float)max_points_part);
            r->setMaxTranslation(max_translation);
            r->setMaxRotation(max_rotation_deg);
            o->odo = r;
        }
        o->w = w;
        o->h = h;
        o->variant = variant;
        for (int i = 0; i < 4; i++) o->K[i] = K[i];
        o->min_depth = min_depth;
        o->max_depth = max_depth;
        if (Kc) {
            o->unregistered = true;
            for (int i = 0; i < 4; i++) o->Kc[i] = Kc[i];
            if (T_cd)
                for (int i = 0; i < 16; i++) o->Tcd[i] = T_cd[i];
            o->mapx.create(h, w, CV_32F);
            o->mapy.create(h, w, CV_32F);
        }
        *out = o;
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV rgbd odometry: ") + e.what());
        return -1;
    }
}

extern "C" void sooc_cvodo_destroy(sooc_cvodo *o) { delete o; }

extern "C" int sooc_cvodo_load(sooc_cvodo *o, const uint8_t *rgb, const float *depth, int sw, int sh, char *err,
                               size_t errcap) {
    try {
        cv::Mat rgb_in(sh, sw, CV_8UC3, const_cast<uint8_t *>(rgb));
        cv::Mat depth_in(sh, sw, CV_32F, const_cast<float *>(depth));
        cv::cvtColor(rgb_in, o->gray_full, cv::COLOR_RGB2GRAY);
        cv::Mat gray, dep;
        if (sw == o->w && sh == o->h) {
            gray = o->gray_full.clone();
            dep = depth_in.clone();
        } else {
            cv::resize(o->gray_full, gray, cv::Size(o->w, o->h), 0, 0, cv::INTER_AREA);
            cv::resize(depth_in, dep, cv::Size(o->w, o->h), 0, 0, cv::INTER_NEAREST);
        }
        if (o->unregistered && o->variant != 1) {
            // colour camera -> depth camera: sample the colour at each depth
            // pixel's 3D point projected into the colour camera
            const double *T = o->Tcd;
            const double fx = o->K[0], fy = o->K[1], cx = o->K[2], cy = o->K[3];
            const double fxc = o->Kc[0], fyc = o->Kc[1], cxc = o->Kc[2], cyc = o->Kc[3];
            for (int y = 0; y < o->h; y++) {
                const float *dr = dep.ptr<float>(y);
                float *mx = o->mapx.ptr<float>(y), *my = o->mapy.ptr<float>(y);
                const double ry = (y - cy) / fy;
                for (int x = 0; x < o->w; x++) {
                    const double rx = (x - cx) / fx;
                    const double z = dr[x];
                    double px, py, pz;
                    if (z > 0 && std::isfinite(z)) {   // p_c = R p_d + t
                        px = T[0] * rx * z + T[1] * ry * z + T[2] * z + T[3];
                        py = T[4] * rx * z + T[5] * ry * z + T[6] * z + T[7];
                        pz = T[8] * rx * z + T[9] * ry * z + T[10] * z + T[11];
                    } else {                            // ray at infinity: rotation only
                        px = T[0] * rx + T[1] * ry + T[2];
                        py = T[4] * rx + T[5] * ry + T[6];
                        pz = T[8] * rx + T[9] * ry + T[10];
                    }
                    if (pz > 1e-9) {
                        mx[x] = (float)(fxc * px / pz + cxc);
                        my[x] = (float)(fyc * py / pz + cyc);
                    } else {
                        mx[x] = my[x] = -1e6f;
                    }
                }
            }
            cv::Mat reg;
            cv::remap(gray, reg, o->mapx, o->mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
            gray = reg;
        }
        // the frame keeps its own buffers: a keyframe outlives later loads
        o->cur = cv::rgbd::OdometryFrame::create(o->variant == 1 ? cv::Mat() : gray, dep);
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV odometry frame: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cvodo_set_keyframe(sooc_cvodo *o, char *err, size_t errcap) {
    try {
        if (!o->cur) {
            set_err(err, errcap, "odometry: no frame loaded");
            return -1;
        }
        o->kf = o->cur;
        o->odo->prepareFrameCache(o->kf, cv::rgbd::OdometryFrame::CACHE_DST);
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV odometry keyframe: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cvodo_track(sooc_cvodo *o, const double init[16], double T_kf_cur[16], char *err,
                                size_t errcap) {
    try {
        if (!o->cur || !o->kf) {
            set_err(err, errcap, "odometry: no keyframe or no frame loaded");
            return -1;
        }
        cv::Mat Rt;
        cv::Mat initRt = init ? to_mat44(init) : cv::Mat();
        bool ok = o->odo->compute(o->cur, o->kf, Rt, initRt);
        if (!ok || Rt.empty()) return 0;
        from_mat44(Rt, T_kf_cur);
        for (int i = 0; i < 16; i++)
            if (!std::isfinite(T_kf_cur[i])) return 0;
        return 1;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV odometry: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cvodo_check(sooc_cvodo *o, const double T[16], double max_diff, int step, double *agree,
                                char *err, size_t errcap) {
    *agree = 0;
    if (!o->cur || !o->kf || o->cur->depth.empty() || o->kf->depth.empty()) {
        set_err(err, errcap, "odometry: no keyframe or no frame loaded");
        return -1;
    }
    sooc_cv::DepthAgreement a =
        sooc_cv::depth_agreement(o->cur->depth, o->kf->depth, o->K, T, o->min_depth, o->max_depth, max_diff, step);
    *agree = a.n ? (double)a.agree / (double)a.n : 0;
    return 0;
}

extern "C" int sooc_cvodo_current(const sooc_cvodo *o, uint8_t *gray, float *depth, int *w, int *h, double K[4],
                                  char *err, size_t errcap) {
    if (!o->cur || o->cur->depth.empty()) {
        set_err(err, errcap, "odometry: no frame loaded");
        return -1;
    }
    *w = o->w;
    *h = o->h;
    for (int i = 0; i < 4; i++) K[i] = o->K[i];
    if (depth)
        for (int y = 0; y < o->h; y++) std::memcpy(depth + (size_t)y * o->w, o->cur->depth.ptr<float>(y), sizeof(float) * o->w);
    if (o->cur->image.empty() || o->cur->image.type() != CV_8UC1) return 1;
    if (gray)
        for (int y = 0; y < o->h; y++) std::memcpy(gray + (size_t)y * o->w, o->cur->image.ptr<uint8_t>(y), (size_t)o->w);
    return 0;
}

// ------------------------------------------------------------ calibration

struct sooc_cvboard {
    int kind = 0, sx = 0, sy = 0;
    double square = 0, marker = 0;
    cv::Ptr<cv::aruco::Dictionary> dict;
    cv::Ptr<cv::aruco::CharucoBoard> board;
};

extern "C" int sooc_cvboard_create(sooc_cvboard **out, int kind, int sx, int sy, double square, double marker,
                                   int dict, char *err, size_t errcap) {
    *out = nullptr;
    try {
        auto *b = new sooc_cvboard();
        b->kind = kind;
        b->sx = sx;
        b->sy = sy;
        b->square = square;
        b->marker = marker;
        if (kind == 0) {
            b->dict = cv::aruco::getPredefinedDictionary(dict);
            b->board = cv::aruco::CharucoBoard::create(sx, sy, (float)square, (float)marker, b->dict);
        }
        *out = b;
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV board: ") + e.what());
        return -1;
    }
}

extern "C" void sooc_cvboard_destroy(sooc_cvboard *b) { delete b; }

extern "C" int sooc_cvboard_npoints(const sooc_cvboard *b) { return (b->sx - 1) * (b->sy - 1); }

extern "C" int sooc_cvboard_draw(const sooc_cvboard *b, uint8_t *gray, int w, int h, char *err, size_t errcap) {
    try {
        cv::Mat out(h, w, CV_8U, gray);
        if (b->kind == 0) {
            cv::Mat img;
            b->board->draw(cv::Size(w, h), img, 0, 1);
            img.copyTo(out);
        } else {
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    int i = (int)((long)x * b->sx / w), j = (int)((long)y * b->sy / h);
                    gray[(size_t)y * w + x] = ((i + j) & 1) ? 255 : 0;
                }
        }
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV board draw: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cvboard_detect(const sooc_cvboard *b, const uint8_t *gray, int w, int h, double *obj,
                                   double *img, int cap, int *n, char *err, size_t errcap) {
    *n = 0;
    try {
        cv::Mat g(h, w, CV_8U, const_cast<uint8_t *>(gray));
        if (b->kind == 0) {
            std::vector<std::vector<cv::Point2f>> corners;
            std::vector<int> ids;
            cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
            cv::aruco::detectMarkers(g, b->dict, corners, ids, params);
            if (ids.empty()) return 0;
            std::vector<cv::Point2f> cc;
            std::vector<int> cid;
            cv::aruco::interpolateCornersCharuco(corners, ids, g, b->board, cc, cid);
            for (size_t i = 0; i < cc.size() && *n < cap; i++) {
                const cv::Point3f &p = b->board->chessboardCorners[(size_t)cid[i]];
                obj[3 * *n] = p.x;
                obj[3 * *n + 1] = p.y;
                obj[3 * *n + 2] = p.z;
                img[2 * *n] = cc[i].x;
                img[2 * *n + 1] = cc[i].y;
                (*n)++;
            }
        } else {
            cv::Size pat(b->sx - 1, b->sy - 1);
            std::vector<cv::Point2f> cc;
            if (!cv::findChessboardCorners(g, pat, cc, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE))
                return 0;
            cv::cornerSubPix(g, cc, cv::Size(5, 5), cv::Size(-1, -1),
                             cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
            for (size_t i = 0; i < cc.size() && *n < cap; i++) {
                obj[3 * *n] = (double)(i % (size_t)pat.width) * b->square;
                obj[3 * *n + 1] = (double)(i / (size_t)pat.width) * b->square;
                obj[3 * *n + 2] = 0;
                img[2 * *n] = cc[i].x;
                img[2 * *n + 1] = cc[i].y;
                (*n)++;
            }
        }
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV board detection: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cv_calibrate(int nv, const int *counts, const double *obj, const double *img, int w, int h,
                                 int dist_n, double K[4], double dist[5], double *rms, double *T_cam_board,
                                 char *err, size_t errcap) {
    try {
        std::vector<std::vector<cv::Point3f>> O((size_t)nv);
        std::vector<std::vector<cv::Point2f>> I((size_t)nv);
        size_t k = 0;
        for (int v = 0; v < nv; v++)
            for (int i = 0; i < counts[v]; i++, k++) {
                O[(size_t)v].emplace_back((float)obj[3 * k], (float)obj[3 * k + 1], (float)obj[3 * k + 2]);
                I[(size_t)v].emplace_back((float)img[2 * k], (float)img[2 * k + 1]);
            }
        int flags = 0;
        if (dist_n == 0)
            flags = cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
        else if (dist_n == 4)
            flags = cv::CALIB_FIX_K3;
        cv::Mat cam = cv::Mat::eye(3, 3, CV_64F), dc = cv::Mat::zeros(5, 1, CV_64F);
        std::vector<cv::Mat> rv, tv;
        *rms = cv::calibrateCamera(O, I, cv::Size(w, h), cam, dc, rv, tv, flags,
                                   cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
        K[0] = cam.at<double>(0, 0);
        K[1] = cam.at<double>(1, 1);
        K[2] = cam.at<double>(0, 2);
        K[3] = cam.at<double>(1, 2);
        for (int i = 0; i < 5; i++) dist[i] = dc.at<double>(i);
        if (T_cam_board)
            for (int v = 0; v < nv; v++) rvec_to_T(rv[(size_t)v], tv[(size_t)v], T_cam_board + 16 * v);
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV calibrateCamera: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cv_pnp(int n, const double *obj, const double *img, const double K[4], const double dist[5],
                           double T_cam_board[16], double *rms, char *err, size_t errcap) {
    try {
        std::vector<cv::Point3d> O;
        std::vector<cv::Point2d> I;
        for (int i = 0; i < n; i++) {
            O.emplace_back(obj[3 * i], obj[3 * i + 1], obj[3 * i + 2]);
            I.emplace_back(img[2 * i], img[2 * i + 1]);
        }
        cv::Mat cam = camera_matrix(K), dc(5, 1, CV_64F);
        for (int i = 0; i < 5; i++) dc.at<double>(i) = dist[i];
        cv::Mat rvec, tvec;
        if (!cv::solvePnP(O, I, cam, dc, rvec, tvec, false, cv::SOLVEPNP_ITERATIVE)) {
            set_err(err, errcap, "solvePnP failed");
            return -1;
        }
        std::vector<cv::Point2d> P;
        cv::projectPoints(O, rvec, tvec, cam, dc, P);
        double s = 0;
        for (int i = 0; i < n; i++) {
            double dx = P[(size_t)i].x - I[(size_t)i].x, dy = P[(size_t)i].y - I[(size_t)i].y;
            s += dx * dx + dy * dy;
        }
        *rms = n ? std::sqrt(s / n) : 0;
        rvec_to_T(rvec, tvec, T_cam_board);
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV solvePnP: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cv_handeye(int n, const double *T_base_ee, const double *T_cam_board, int method,
                               double T_ee_cam[16], char *err, size_t errcap) {
    try {
        std::vector<cv::Mat> Rg, tg, Rc, tc;
        for (int i = 0; i < n; i++) {
            cv::Mat A = to_mat44(T_base_ee + 16 * i), B = to_mat44(T_cam_board + 16 * i);
            Rg.push_back(A(cv::Rect(0, 0, 3, 3)).clone());
            tg.push_back(A(cv::Rect(3, 0, 1, 3)).clone());
            Rc.push_back(B(cv::Rect(0, 0, 3, 3)).clone());
            tc.push_back(B(cv::Rect(3, 0, 1, 3)).clone());
        }
        cv::Mat R, t;
        cv::calibrateHandEye(Rg, tg, Rc, tc, R, t, (cv::HandEyeCalibrationMethod)method);
        rt_to_T(R, t, T_ee_cam);
        for (int i = 0; i < 16; i++)
            if (!std::isfinite(T_ee_cam[i])) {
                set_err(err, errcap, "calibrateHandEye returned a non-finite transform");
                return -1;
            }
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("OpenCV calibrateHandEye: ") + e.what());
        return -1;
    }
}

extern "C" int sooc_cv_yaml_read(const char *path, int *w, int *h, double K[9], char *err, size_t errcap) {
    try {
        cv::FileStorage fs(path, cv::FileStorage::READ);
        if (!fs.isOpened()) {
            set_err(err, errcap, std::string(path) + ": OpenCV FileStorage cannot open it");
            return -1;
        }
        *w = (int)fs["image_width"];
        *h = (int)fs["image_height"];
        cv::FileNode cm = fs["camera_matrix"];
        if (cm.empty()) {
            set_err(err, errcap, std::string(path) + ": OpenCV finds no camera_matrix");
            return -1;
        }
        if (cm.isMap() && !cm["data"].empty() && cm["dt"].empty()) {
            cv::FileNode d = cm["data"];
            if (d.size() != 9) {
                set_err(err, errcap, std::string(path) + ": camera_matrix.data does not hold 9 numbers");
                return -1;
            }
            for (int i = 0; i < 9; i++) K[i] = (double)d[i];
        } else {
            cv::Mat m;
            cm >> m;
            if (m.rows != 3 || m.cols != 3) {
                set_err(err, errcap, std::string(path) + ": camera_matrix is not 3x3");
                return -1;
            }
            m.convertTo(m, CV_64F);
            for (int i = 0; i < 9; i++) K[i] = m.at<double>(i / 3, i % 3);
        }
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string(path) + ": OpenCV: " + e.what());
        return -1;
    }
}
