/*
 * sooc3d core: the base every other header builds on. Status codes and
 * messages, the log callback, the counted allocator, RNG, clocks, progress
 * line, CRC32, atomic file saving; the geometry math (SE(3), quaternions,
 * pinhole intrinsics and distortion); images and their PNG / JPEG / depth
 * I/O.
 *
 * Sections: status codes, log callback, allocator, RNG, clocks, files
 * (core); geometry: SE(3), quaternions, camera intrinsics (geom); images:
 * PNG / JPEG / depth I/O (image).
 *
 * Contract (CONTRIBUTING.md "Coding rules"), for every section below where
 * the section does not say otherwise. Ownership: the caller owns what it
 * creates and releases it with the matching _destroy / _free / _close
 * (NULL-safe); pointers a getter returns are borrowed and live as long as
 * their object. Threads: an object is used by one thread at a time;
 * functions without an object are reentrant. Errors: a status other than
 * SOOC_OK comes with a message naming the file, key or line (sooc_errmsg);
 * nothing here prints or exits.
 */
#ifndef SOOC3D_CORE_H
#define SOOC3D_CORE_H

#include <stddef.h>
#include <stdint.h>
#include <stdarg.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ==== status codes, log callback, allocator, RNG, clocks, files (core) === */

/*
 * sooc3d core: status codes and messages, the log callback, the counted
 * allocator, a deterministic RNG, clocks, a terminal progress line, CRC32 and
 * atomic file saving.
 *
 * Conventions used by every module:
 *  - Fallible functions return sooc_status (0 = OK, negative = error). When
 *    they fail they also leave a message, readable with sooc_errmsg() on the
 *    same thread until the next failure. Messages name the file/key/line
 *    involved, e.g. "calib/x.yaml:12: camera_matrix: expected 9 numbers".
 *  - The library never prints and never exits. Text goes through the log
 *    callback (default: none; the CLI installs one that writes to stderr).
 *  - Heap memory comes from sooc_malloc/sooc_calloc/sooc_free: 64-byte aligned,
 *    counted, and with fault injection for tests.
 */

/* ---------------------------------------------------------------- status */

typedef enum sooc_status {
    SOOC_OK = 0,
    SOOC_ERR = -1,         /* generic failure                                */
    SOOC_ENOMEM = -2,      /* allocation failed                              */
    SOOC_EINVAL = -3,      /* bad argument or bad value in an input file     */
    SOOC_EIO = -4,         /* read/write/open failed                         */
    SOOC_EFORMAT = -5,     /* file is malformed, truncated or corrupt        */
    SOOC_EVERSION = -6,    /* file has a version/config we cannot read       */
    SOOC_ENOTFOUND = -7,   /* missing file, device, key or entry             */
    SOOC_EUNSUPPORTED = -8,/* feature not built in or not supported by device */
    SOOC_ETIMEOUT = -9,    /* timed out                                      */
    SOOC_EBUSY = -10,      /* resource busy (e.g. seqlock retries exhausted) */
    SOOC_EEOF = -11,       /* end of stream                                  */
    SOOC_ENUMERIC = -12,   /* non-finite value where a finite one is needed  */
    SOOC_EINTERRUPTED = -13/* stopped by a signal / stop request            */
} sooc_status;

/* Name of a status code, e.g. "EFORMAT". Never NULL. */
const char *sooc_status_str(sooc_status s);

/* Record an error message for the calling thread and return `s` (so callers
 * can write `return sooc_seterr(SOOC_EINVAL, "%s:%d: ...", path, line);`). */
sooc_status sooc_seterr(sooc_status s, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Prefix the current message with "<prefix>: " (adds context while unwinding). */
sooc_status sooc_adderr(sooc_status s, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* The calling thread's last error message ("" if none). Thread-local storage. */
const char *sooc_errmsg(void);
void sooc_clearerr(void);

/* Always-on assertion for contract violations (programming errors, not input
 * errors). Calls the log callback at FATAL and then abort(). */
_Noreturn void sooc_assert_fail(const char *expr, const char *file, int line);
#define SOOC_ASSERT(x) ((x) ? (void)0 : sooc_assert_fail(#x, __FILE__, __LINE__))

/* ------------------------------------------------------------------- log */

typedef enum sooc_log_level {
    SOOC_LOG_DEBUG = 0, SOOC_LOG_INFO = 1, SOOC_LOG_WARN = 2,
    SOOC_LOG_ERROR = 3, SOOC_LOG_FATAL = 4
} sooc_log_level;

typedef void (*sooc_log_fn)(void *user, sooc_log_level level, const char *msg);

/* Install the log sink (NULL = drop everything). Thread-safe to call log;
 * set the callback before starting threads. */
void sooc_log_set_callback(sooc_log_fn fn, void *user);
void sooc_log_set_level(sooc_log_level min_level);
sooc_log_level sooc_log_get_level(void);
void sooc_log(sooc_log_level level, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Parse "debug|info|warn|error"; returns SOOC_EINVAL on anything else. */
sooc_status sooc_log_level_parse(const char *s, sooc_log_level *out);

/* ------------------------------------------------------------- allocator */

/* 64-byte aligned allocation. Returns NULL on failure (and sets the error
 * message). sooc_free(NULL) is a no-op. */
void *sooc_malloc(size_t n);
void *sooc_calloc(size_t count, size_t size);   /* overflow-checked, zeroed */
void *sooc_realloc(void *p, size_t n);           /* keeps 64-byte alignment */
void sooc_free(void *p);
char *sooc_strdup(const char *s);

typedef struct sooc_alloc_stats {
    uint64_t live_bytes, peak_bytes, n_alloc, n_free;
} sooc_alloc_stats;
void sooc_alloc_get_stats(sooc_alloc_stats *out);
/* Test hook: after `n_ok` more successful allocations, the next `n_fail`
 * allocations fail. (0, 0) disables injection. */
void sooc_alloc_fault_inject(uint64_t n_ok, uint64_t n_fail);

/* ------------------------------------------------------------------- RNG */

/* xoshiro256** seeded through splitmix64 from (seed, stream). Distinct streams
 * are independent, so work item i can own stream i: results then do not
 * depend on the thread count. Pure value type; copy it freely. */
typedef struct sooc_rng { uint64_t s[4]; } sooc_rng;

void sooc_rng_seed(sooc_rng *r, uint64_t seed, uint64_t stream);
uint64_t sooc_rng_u64(sooc_rng *r);
uint32_t sooc_rng_u32(sooc_rng *r);
double sooc_rng_uniform(sooc_rng *r);                  /* [0, 1), 53 bits   */
float sooc_rng_uniformf(sooc_rng *r);                  /* [0, 1), 24 bits   */
double sooc_rng_uniform_open(sooc_rng *r);             /* (0, 1)            */
double sooc_rng_range(sooc_rng *r, double lo, double hi);
uint32_t sooc_rng_below(sooc_rng *r, uint32_t n);      /* [0, n), unbiased  */
double sooc_rng_normal(sooc_rng *r);                   /* N(0,1), Box-Muller, no cached state */
double sooc_rng_logistic(sooc_rng *r);                 /* log U - log(1-U)  */

/* ----------------------------------------------------------------- clock */

int64_t sooc_now_ns(void);        /* CLOCK_MONOTONIC */
int64_t sooc_realtime_ns(void);   /* CLOCK_REALTIME  */
double sooc_seconds(void);        /* CLOCK_MONOTONIC in seconds */

/* -------------------------------------------------------------- progress */

/* A one-line progress display: "label  123/456  27% 12.3 it/s ETA 0:42  extra".
 * Redrawn in place when stderr is a terminal (at most 10 Hz), otherwise a full
 * line every `log_every_s` seconds. Output goes to stderr: this is for CLI
 * programs, not the library. */
typedef struct sooc_progress {
    const char *label;
    uint64_t total, done;
    double t0, t_last;
    double log_every_s;
    int tty;
    int last_len;
} sooc_progress;

void sooc_progress_begin(sooc_progress *p, const char *label, uint64_t total);
/* Set `done` and redraw; `extra` (may be NULL) is appended, e.g. losses. */
void sooc_progress_update(sooc_progress *p, uint64_t done, const char *extra);
void sooc_progress_end(sooc_progress *p, const char *extra);

/* ------------------------------------------------------------------ files */

/* zlib CRC-32 of a buffer; `crc` is the running value (start from 0). */
uint32_t sooc_crc32(uint32_t crc, const void *buf, size_t n);

/* Atomic save: write to "<path>.tmp.<pid>", fsync, rename over `path`, fsync
 * the directory. On any failure the old file is left untouched. */
sooc_status sooc_file_write_atomic(const char *path, const void *data, size_t n);
/* Write `data` to "<path>.tmp" and rename it over `path`, without fsync: bulk
 * dataset files (frames, meshes, pictures) that a crash may lose whole but
 * never leaves half-written. */
sooc_status sooc_file_write_bulk(const char *path, const void *data, size_t n);

/* Streaming variant: open a temp file next to `path`, write with
 * sooc_afile_write, then sooc_afile_commit (fsync + rename) or
 * sooc_afile_abort (unlink). A CRC32 of everything written is kept. */
typedef struct sooc_afile {
    void *fp;          /* FILE* */
    char *path, *tmp;
    uint32_t crc;
    uint64_t nbytes;
    int failed;
} sooc_afile;
sooc_status sooc_afile_open(sooc_afile *f, const char *path);
sooc_status sooc_afile_write(sooc_afile *f, const void *data, size_t n);
sooc_status sooc_afile_commit(sooc_afile *f);
void sooc_afile_abort(sooc_afile *f);

/* ------------------------------------------------------- string builder */

/* A growable text buffer (sooc_malloc'd, NUL-terminated): printf appends;
 * after an allocation or format failure `oom` is set and later appends do
 * nothing, so a caller checks once at the end. The caller owns p (sooc_free). */
typedef struct sooc_strbuf {
    char *p;
    size_t n, cap;
    int oom;
} sooc_strbuf;
void sooc_strbuf_printf(sooc_strbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Read a whole file into a sooc_malloc'd buffer (NUL-terminated for text use).
 * Refuses files larger than max_bytes with SOOC_EFORMAT. */
sooc_status sooc_file_read_all(const char *path, size_t max_bytes, void **out, size_t *n);
/* A file's content identity, as a map database stores its model's
 * (mapstore model_id): "fnv1a64:<16 hex> bytes:<n>", the 64-bit FNV-1a of
 * every byte (of a checkpoint too: a CRC32 of a file that ends with its own
 * CRC32 is a constant). cap >= 48; *hash may be NULL. Files up to 2 GiB. */
sooc_status sooc_file_id(const char *path, char *id, size_t cap, uint64_t *hash);
int sooc_file_exists(const char *path);
int sooc_dir_exists(const char *path);
/* mkdir -p */
sooc_status sooc_mkdirs(const char *path);
/* The folder that holds path, into `out` (cap bytes, truncated): "." for a bare
 * name, "/" for a name at the root; trailing slashes of path are ignored. */
void sooc_path_parent(const char *path, char *out, size_t cap);
/* Join path parts into `out` (cap bytes). Fails with SOOC_EINVAL if too long. */
sooc_status sooc_path_join(char *out, size_t cap, const char *a, const char *b);

/* ==== geometry: SE(3), quaternions, camera intrinsics (geom) ============= */

/*
 * sooc3d geometry: small dense vectors and matrices in double, SE(3) poses,
 * quaternions, the pinhole camera, and the gravity-aligned camera frame G_t.
 *
 * Conventions (docs/formats.md §1):
 *  - Matrices are row-major double[9] (3x3) or double[16] (4x4).
 *  - A pose T_ab maps points in frame b to frame a: p_a = T_ab * p_b.
 *    Camera poses are T_wc (camera-to-world).
 *  - Camera optical axes are OpenCV's: x right, y down, z forward.
 *  - The world is gravity-aligned with +y up and the floor at y = 0.
 *  - Quaternions are Hamilton, stored (x, y, z, w) as in TUM and ROS.
 *  - Floor poses (x, z, yaw): yaw is a rotation about +y with
 *    R_y(yaw) = [[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]].
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* ---- 3-vectors ---- */
void sooc_v3_sub(double out[3], const double a[3], const double b[3]);
void sooc_v3_add(double out[3], const double a[3], const double b[3]);
void sooc_v3_scale(double out[3], const double a[3], double s);
double sooc_v3_dot(const double a[3], const double b[3]);
void sooc_v3_cross(double out[3], const double a[3], const double b[3]);
double sooc_v3_norm(const double a[3]);
/* Normalise in place; returns the old norm (0 leaves the vector unchanged). */
double sooc_v3_normalize(double a[3]);

/* ---- 3x3 ---- */
void sooc_m3_identity(double R[9]);
void sooc_m3_mul(double out[9], const double A[9], const double B[9]);  /* out may alias neither */
void sooc_m3_transpose(double out[9], const double A[9]);
void sooc_m3_mulv(double out[3], const double R[9], const double v[3]);
void sooc_m3_tmulv(double out[3], const double R[9], const double v[3]); /* R^T v */
double sooc_m3_det(const double R[9]);
/* max |R R^T - I| entry and |det R - 1|; a rotation passes at tol ~1e-4 for
 * values read from 6-decimal text files. */
int sooc_m3_is_rotation(const double R[9], double tol, double *err_out);
void sooc_m3_rot_y(double R[9], double yaw);

/* ---- quaternions (x, y, z, w) ---- */
void sooc_quat_to_m3(double R[9], const double q[4]);   /* q need not be unit; it is normalised */
void sooc_m3_to_quat(double q[4], const double R[9]);   /* w >= 0 */
void sooc_quat_slerp(double out[4], const double a[4], const double b[4], double t);

/* ---- SE(3) 4x4 ---- */
void sooc_se3_identity(double T[16]);
void sooc_se3_from_rt(double T[16], const double R[9], const double t[3]);
void sooc_se3_to_rt(double R[9], double t[3], const double T[16]);
void sooc_se3_mul(double out[16], const double A[16], const double B[16]); /* out aliases neither */
void sooc_se3_inverse(double out[16], const double T[16]);
void sooc_se3_apply(double out[3], const double T[16], const double p[3]);
void sooc_se3_rotate(double out[3], const double T[16], const double v[3]);
/* Interpolate poses: SLERP on rotation, linear on translation. */
void sooc_se3_interp(double out[16], const double A[16], const double B[16], double t);

/* ---- pinhole camera ---- */
typedef enum sooc_distortion {
    SOOC_DIST_NONE = 0, SOOC_DIST_PLUMB_BOB = 1, SOOC_DIST_RATIONAL = 2, SOOC_DIST_EQUIDISTANT = 3
} sooc_distortion;

typedef struct sooc_intrinsics {
    int width, height;
    double fx, fy, cx, cy;
    sooc_distortion dist_model;
    double dist[8];          /* OpenCV order: k1 k2 p1 p2 k3 [k4 k5 k6] */
} sooc_intrinsics;

/* Unit ray direction (camera frame) through pixel centre (u + 0.5, v + 0.5)
 * for an undistorted camera; returns the z component of the unnormalised ray
 * (1/|ray|), used to convert planar depth z to Euclidean distance. */
double sooc_cam_ray(const sooc_intrinsics *K, double u, double v, double dir[3]);
/* Project a camera-frame point; returns 0 if z <= 0. Pixel coordinates are
 * continuous (pixel i covers [i, i+1)). */
int sooc_cam_project(const sooc_intrinsics *K, const double p[3], double *u, double *v);
/* Scale intrinsics for a resize from (K->width, K->height) to (w, h), after an
 * optional crop (x0, y0, cw, ch) in source pixels. */
void sooc_cam_crop_resize(sooc_intrinsics *out, const sooc_intrinsics *K, int x0, int y0, int cw,
                          int ch, int w, int h);

/* ---- gravity-aligned camera frame G_t (the SOOC3D paper) ---- */
/* Given a camera pose T_wc in a +y-up world with the floor at y = 0, fill
 * T_wg (G-to-world: origin at the camera centre, y = world up, z = camera
 * forward projected on the floor plane) and the camera height h (y of the
 * centre). Also returns pitch (rad, negative when looking down) and roll.
 * Fails with SOOC_EINVAL if the camera looks straight up or down. */
sooc_status sooc_gframe(const double T_wc[16], double T_wg[16], double *h, double *pitch, double *roll);

/* Floor pose (x, z, yaw) conversions between world and a G frame with
 * ground position (Xc, Zc) and yaw psi:
 *   (px, pz) = R2(psi)^T ((X, Z) - (Xc, Zc)),  theta = Theta - psi.
 * R2 uses the same sign convention as R_y. */
typedef struct sooc_floor_frame { double X, Z, psi; } sooc_floor_frame;
void sooc_floor_frame_of(sooc_floor_frame *f, const double T_wg[16]);
void sooc_floor_to_local(const sooc_floor_frame *f, const double world[3], double local[3]);
void sooc_floor_to_world(const sooc_floor_frame *f, const double local[3], double world[3]);
/* Wrap an angle to (-pi, pi]. */
double sooc_wrap_angle(double a);

/* ==== images: PNG / JPEG / depth I/O (image) ============================= */

/*
 * sooc3d images: PNG / PGM / JPEG input and output, and simple drawing for pictures
 * (filled/outlined rectangles, lines, circles, a built-in 5x7 bitmap font,
 * colour maps for depth and ids, contact sheets).
 *
 * Pixel formats: RGB8 (3 bytes per pixel), GRAY8, GRAY16. Pixels are stored
 * row-major, top row first, with no row padding. GRAY16 samples are kept in
 * HOST byte order in memory; the PNG and PGM codecs convert from/to the
 * big-endian order those formats use on disk.
 *
 * Ownership: an image owns `data` (sooc_malloc); release with
 * sooc_image_free. A zero-initialised sooc_image is "empty" and may be passed
 * to any function that fills an image (it is (re)allocated as needed).
 *
 * Thread safety: all functions are reentrant; distinct images may be used
 * from distinct threads.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef enum sooc_pixfmt {
    SOOC_PIX_NONE = 0,
    SOOC_PIX_GRAY8 = 1,   /* 1 byte per pixel                       */
    SOOC_PIX_GRAY16 = 2,  /* uint16 per pixel, host byte order       */
    SOOC_PIX_RGB8 = 3     /* 3 bytes per pixel, R G B                */
} sooc_pixfmt;

typedef struct sooc_image {
    int width, height;
    sooc_pixfmt fmt;
    void *data;           /* uint8_t* (GRAY8, RGB8) or uint16_t* (GRAY16) */
} sooc_image;

/* Name of a pixel format ("rgb8", "gray8", "gray16", "none"). */
const char *sooc_pixfmt_name(sooc_pixfmt f);
/* Bytes per pixel (0 for NONE). */
int sooc_pixfmt_bytes(sooc_pixfmt f);

/* (Re)allocate `img` as w x h of format fmt, zero-filled. Reuses the buffer
 * when the size and format already match. */
sooc_status sooc_image_alloc(sooc_image *img, int w, int h, sooc_pixfmt fmt);
void sooc_image_free(sooc_image *img);          /* NULL-safe; leaves it empty */
/* Deep copy into dst (reallocated). */
sooc_status sooc_image_copy(sooc_image *dst, const sooc_image *src);

/* --------------------------------------------------------------- codecs */

/* Limits of the readers (PNG and PGM): width and height <= 16384 and at most
 * 256 MiB of decoded pixels; larger files are rejected (EFORMAT, naming the
 * file) before anything is allocated. */
#define SOOC_IMAGE_READ_MAX_DIM 16384
#define SOOC_IMAGE_READ_MAX_BYTES ((size_t)256 << 20)

/* Read a PNG. Gray 1/2/4/8-bit -> GRAY8, gray 16-bit -> GRAY16, RGB or
 * palette -> RGB8 (16-bit colour is reduced to 8 bits), alpha is dropped.
 * Errors name the file: ENOTFOUND (missing), EFORMAT (not a PNG / corrupt). */
sooc_status sooc_png_read(const char *path, sooc_image *out);
/* Read the size and format a PNG would decode to, without decoding pixels. */
sooc_status sooc_png_info(const char *path, int *w, int *h, sooc_pixfmt *fmt);
/* Write a PNG via a temp file + rename (no fsync). `level` is the zlib level
 * 0..9, or -1 for the default (6). Output bytes are deterministic. */
sooc_status sooc_png_write(const char *path, const sooc_image *img, int level);
/* Decode n bytes of PNG in memory (ROS CompressedImage messages) with the
 * reader's conversions and limits; `name` (may be NULL) is used in messages. */
sooc_status sooc_png_decode(const void *buf, size_t n, const char *name, sooc_image *out);
/* Encode to a sooc_malloc'd buffer (*out, *n); the caller frees. */
sooc_status sooc_png_encode(const sooc_image *img, int level, void **out, size_t *n);

/* Read a binary PGM (P5) with maxval <= 255 (-> GRAY8) or 256..65535
 * (-> GRAY16, samples big-endian on disk as the Netpbm spec says). ASCII P2
 * is accepted too. Comments (#) in the header are skipped. */
sooc_status sooc_pgm_read(const char *path, sooc_image *out);
/* Write a binary PGM from GRAY8 or GRAY16 (maxval 255 or 65535). */
sooc_status sooc_pgm_write(const char *path, const sooc_image *img);

/* JPEG through libjpeg-turbo (baseline, progressive, any chroma
 * subsampling, Motion-JPEG frames without Huffman tables). 3-component
 * (YCbCr/RGB) -> RGB8, 1-component -> GRAY8; CMYK is EUNSUPPORTED. Same size
 * limits as PNG. A truncated or corrupt stream (premature end, bad Huffman
 * code, lost sync, bad progression) is EFORMAT "<name>: corrupt JPEG: ..."
 * and `out` holds no partial image that could be mistaken for a good one
 * (its buffer may have been reallocated). libjpeg never prints. */
sooc_status sooc_jpeg_read(const char *path, sooc_image *out);
/* Decode n bytes in memory (V4L2 MJPEG buffers); `name` (may be NULL) is used
 * in messages in place of a path. */
sooc_status sooc_jpeg_decode(const void *buf, size_t n, const char *name, sooc_image *out);
/* Encode RGB8 or GRAY8 at `quality` 1..100 (else 90), 4:2:0, to a sooc_malloc'd
 * buffer; and write a file atomically (temp + rename). */
sooc_status sooc_jpeg_encode(const sooc_image *img, int quality, void **out, size_t *n);
sooc_status sooc_jpeg_write(const char *path, const sooc_image *img, int quality);

/* Read any supported image by content, whatever its extension: PNG
 * signature, "P5"/"P2" (PGM), FF D8 FF (JPEG). */
sooc_status sooc_image_read(const char *path, sooc_image *out);
/* Size and format `path` would decode to, by content (PNG and JPEG read only
 * the header). */
sooc_status sooc_image_info(const char *path, int *w, int *h, sooc_pixfmt *fmt);

/* ------------------------------------------------------------- drawing */
/* All drawing functions work on RGB8 images, clip to the image, and never
 * fail (coordinates may be anywhere). Colours are packed 0xRRGGBB. */

#define SOOC_RGB(r, g, b) ((uint32_t)(((uint32_t)(r) << 16) | ((uint32_t)(g) << 8) | (uint32_t)(b)))

void sooc_draw_fill(sooc_image *img, uint32_t rgb);
void sooc_draw_pixel(sooc_image *img, int x, int y, uint32_t rgb);
/* Rectangle [x, x+w) x [y, y+h); outline of the given thickness, or filled
 * when thickness <= 0. */
void sooc_draw_rect(sooc_image *img, int x, int y, int w, int h, uint32_t rgb, int thickness);
/* Bresenham line, both end points included; thickness >= 1 (square pen). */
void sooc_draw_line(sooc_image *img, int x0, int y0, int x1, int y1, uint32_t rgb, int thickness);
/* Circle of radius r around (cx, cy): filled when `filled`, else 1-px outline. */
void sooc_draw_circle(sooc_image *img, int cx, int cy, int r, uint32_t rgb, int filled);
/* Text in the built-in 5x7 font (ASCII 32..126; others draw as '?'), each
 * glyph cell 6x8 pixels times `scale` (>= 1). '\n' starts a new line. The
 * top-left of the first glyph cell is (x, y). If bg is not SOOC_DRAW_NOBG,
 * the cells are filled with bg first. */
#define SOOC_DRAW_NOBG 0xFFFFFFFFu
void sooc_draw_text(sooc_image *img, int x, int y, const char *text, uint32_t fg, uint32_t bg,
                    int scale);
/* Size in pixels of `text` drawn at `scale` (widest line x number of lines). */
void sooc_text_size(const char *text, int scale, int *w, int *h);
/* Copy src (RGB8, GRAY8 or GRAY16 (>>8)) into dst (RGB8) at (x, y), each
 * source pixel becoming a `scale` x `scale` block (nearest neighbour). */
void sooc_draw_blit(sooc_image *dst, const sooc_image *src, int x, int y, int scale);

/* ---------------------------------------------------------- colour maps */

/* Turbo colour map (Google), t in [0, 1] (clamped). */
uint32_t sooc_cmap_turbo(double t);
/* Viridis-like colour map, t in [0, 1] (clamped). */
uint32_t sooc_cmap_viridis(double t);
/* A distinct colour per id: 0 -> dark grey, others well separated hues
 * (golden-angle hue, alternating value), the same in every run. */
uint32_t sooc_cmap_id(uint32_t id);

/* Colourise a depth map (H*W floats in metres, `stride` floats per row =
 * width when 0) into an RGB8 image with turbo over [dmin, dmax]; depth <= 0
 * or non-finite pixels are black. */
sooc_status sooc_image_from_depth(sooc_image *out, const float *depth, int w, int h, double dmin,
                                  double dmax);
/* Colourise an id map (H*W uint16) with sooc_cmap_id. */
sooc_status sooc_image_from_ids(sooc_image *out, const uint16_t *ids, int w, int h);
/* Wrap RGB8 bytes (H*W*3) into a new image (copied). */
sooc_status sooc_image_from_rgb(sooc_image *out, const uint8_t *rgb, int w, int h);

/* --------------------------------------------------------- contact sheet */

/* A grid of `n` tiles, `ncols` per row, each tile magnified by `scale`
 * (nearest), with its label (may be NULL) printed under it in the built-in
 * font. Cells are sized to the largest tile; the background is dark grey.
 * An optional `title` (may be NULL) is printed on top. Tiles may be RGB8,
 * GRAY8 or GRAY16; NULL tiles leave an empty cell. */
sooc_status sooc_image_contact_sheet(sooc_image *out, const sooc_image *const *tiles,
                                     const char *const *labels, int n, int ncols, int scale,
                                     const char *title);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_CORE_H */
