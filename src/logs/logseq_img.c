/* Image messages to frame pixels: colour encodings to RGB8, depth encodings
 * to metres, compressed images through the data module's PNG/JPEG codecs,
 * compressedDepth, and depth registration into the colour camera. */
#include "logseq_impl.h"
#include "logs_impl.h"

#include <math.h>
#include <stdio.h>

sooc_logs_pix sooc_logs_pix_parse(const char *e) {
    static const struct { const char *name; sooc_logs_pix p; } t[] = {
        {"rgb8", LOGS_PIX_RGB8}, {"bgr8", LOGS_PIX_BGR8}, {"rgba8", LOGS_PIX_RGBA8}, {"bgra8", LOGS_PIX_BGRA8},
        {"mono8", LOGS_PIX_MONO8}, {"8UC1", LOGS_PIX_MONO8}, {"8UC3", LOGS_PIX_BGR8}, {"8UC4", LOGS_PIX_BGRA8},
        {"mono16", LOGS_PIX_U16}, {"16UC1", LOGS_PIX_U16}, {"32FC1", LOGS_PIX_F32}};
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (!strcmp(e, t[i].name)) return t[i].p;
    return LOGS_PIX_NONE;
}

int sooc_logs_pix_is_depth(sooc_logs_pix p) { return p == LOGS_PIX_U16 || p == LOGS_PIX_F32; }

static int pix_bytes(sooc_logs_pix p) {
    switch (p) {
    case LOGS_PIX_RGB8: case LOGS_PIX_BGR8: return 3;
    case LOGS_PIX_RGBA8: case LOGS_PIX_BGRA8: case LOGS_PIX_F32: return 4;
    case LOGS_PIX_MONO8: return 1;
    case LOGS_PIX_U16: return 2;
    default: return 0;
    }
}

static sooc_status check_rows(const sooc_ros_image *im, sooc_logs_pix p, int w, int h) {
    if (im->width != w || im->height != h)
        return sooc_seterr(SOOC_EFORMAT, "image is %dx%d, expected %dx%d (the stream changed size)", im->width,
                           im->height, w, h);
    if (im->step < (size_t)w * (size_t)pix_bytes(p))
        return sooc_seterr(SOOC_EFORMAT, "%s image rows of %zu bytes are shorter than %d pixels", im->encoding,
                           im->step, w);
    return SOOC_OK;
}

sooc_status sooc_logs_color_image(const sooc_ros_image *im, uint8_t *rgb, int w, int h) {
    sooc_logs_pix p = sooc_logs_pix_parse(im->encoding);
    if (p == LOGS_PIX_NONE || sooc_logs_pix_is_depth(p))
        return sooc_seterr(SOOC_EUNSUPPORTED, "unknown colour encoding '%s' (rgb8, bgr8, rgba8, bgra8, mono8)",
                           im->encoding);
    sooc_status st = check_rows(im, p, w, h);
    if (st) return st;
    int bpp = pix_bytes(p), sw = p == LOGS_PIX_BGR8 || p == LOGS_PIX_BGRA8;
    for (int y = 0; y < h; y++) {
        const uint8_t *s = im->data + (size_t)y * im->step;
        uint8_t *d = rgb + (size_t)y * (size_t)w * 3;
        if (p == LOGS_PIX_RGB8) {
            memcpy(d, s, (size_t)w * 3);
        } else if (p == LOGS_PIX_MONO8) {
            for (int x = 0; x < w; x++) d[3 * x] = d[3 * x + 1] = d[3 * x + 2] = s[x];
        } else {
            for (int x = 0; x < w; x++) {
                const uint8_t *q = s + (size_t)x * (size_t)bpp;
                d[3 * x] = q[sw ? 2 : 0];
                d[3 * x + 1] = q[1];
                d[3 * x + 2] = q[sw ? 0 : 2];
            }
        }
    }
    return SOOC_OK;
}

sooc_status sooc_logs_color_compressed(const sooc_ros_cimage *ci, sooc_image *img, const char *name) {
    const uint8_t *d = ci->data;
    if (ci->size >= 3 && d[0] == 0xFF && d[1] == 0xD8 && d[2] == 0xFF) return sooc_jpeg_decode(d, ci->size, name, img);
    if (ci->size >= 8 && d[0] == 0x89 && d[1] == 'P' && d[2] == 'N' && d[3] == 'G')
        return sooc_png_decode(d, ci->size, name, img);
    return sooc_seterr(SOOC_EUNSUPPORTED, "%s: compressed image format '%s' is not JPEG or PNG", name, ci->format);
}

static uint16_t u16(const uint8_t *q, int be) { return be ? (uint16_t)((q[0] << 8) | q[1]) : (uint16_t)(q[0] | (q[1] << 8)); }

sooc_status sooc_logs_depth_image(const sooc_ros_image *im, double scale, float *z, int w, int h) {
    sooc_logs_pix p = sooc_logs_pix_parse(im->encoding);
    if (!sooc_logs_pix_is_depth(p))
        return sooc_seterr(SOOC_EUNSUPPORTED, "unknown depth encoding '%s' (16UC1, mono16, 32FC1)", im->encoding);
    sooc_status st = check_rows(im, p, w, h);
    if (st) return st;
    int be = im->bigendian != 0;
    for (int y = 0; y < h; y++) {
        const uint8_t *s = im->data + (size_t)y * im->step;
        float *d = z + (size_t)y * (size_t)w;
        if (p == LOGS_PIX_U16) {
            for (int x = 0; x < w; x++) d[x] = (float)(u16(s + 2 * x, be) * scale);
        } else {
            for (int x = 0; x < w; x++) {
                const uint8_t *q = s + 4 * x;
                uint32_t v = be ? ((uint32_t)q[0] << 24) | ((uint32_t)q[1] << 16) | ((uint32_t)q[2] << 8) | q[3]
                                : logs_u32(q);
                float f;
                memcpy(&f, &v, 4);
                d[x] = isfinite(f) && f > 0 ? f : 0.0f;
            }
        }
    }
    return SOOC_OK;
}

sooc_status sooc_logs_depth_compressed(const sooc_ros_cimage *ci, double scale, sooc_image *img, float **z, size_t *cap,
                                  int *w, int *h, const char *name) {
    const char *f = ci->format;
    int is_f32 = !strncmp(f, "32FC1", 5);
    if (strstr(f, "rvl"))
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: compressedDepth format '%s' (RVL) is not read; record with png", name,
                           f);
    if (!is_f32 && strncmp(f, "16UC1", 5) && strncmp(f, "mono16", 6))
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: compressedDepth of '%s' (16UC1 and 32FC1 are read)", name, f);
    const uint8_t *d = ci->data;
    size_t n = ci->size, off = 12;
    if (n >= 8 && d[0] == 0x89 && d[1] == 'P') off = 0;   /* no configuration header */
    if (n < off + 8) return sooc_seterr(SOOC_EFORMAT, "%s: compressedDepth message of %zu bytes", name, n);
    float qa = 0, qb = 0;
    if (off) {
        memcpy(&qa, d + 4, 4);
        memcpy(&qb, d + 8, 4);
    }
    sooc_status st = sooc_png_decode(d + off, n - off, name, img);
    if (st) return st;
    if (img->fmt != SOOC_PIX_GRAY16)
        return sooc_seterr(SOOC_EFORMAT, "%s: compressedDepth PNG is %s, expected 16-bit", name,
                           sooc_pixfmt_name(img->fmt));
    size_t np = (size_t)img->width * (size_t)img->height;
    if ((st = sooc_logs_reserve((uint8_t **)z, cap, np * sizeof(float)))) return st;
    const uint16_t *v = img->data;
    for (size_t k = 0; k < np; k++) {
        if (!v[k]) (*z)[k] = 0;
        else if (is_f32) {
            float zz = qa / ((float)v[k] - qb);
            (*z)[k] = isfinite(zz) && zz > 0 ? zz : 0.0f;
        } else (*z)[k] = (float)(v[k] * scale);
    }
    *w = img->width;
    *h = img->height;
    return SOOC_OK;
}

void sooc_logs_register_depth(const float *zd, const sooc_intrinsics *Kd, const double T[16], float *out,
                         const sooc_intrinsics *Kc) {
    const int wd = Kd->width, hd = Kd->height, wc = Kc->width, hc = Kc->height;
    for (size_t k = 0; k < (size_t)wc * (size_t)hc; k++) out[k] = 0;
    const double ifx = 1.0 / Kd->fx, ify = 1.0 / Kd->fy;
    /* a depth pixel spans about fc/fd colour pixels at equal depth */
    const double sx = Kc->fx / Kd->fx, sy = Kc->fy / Kd->fy;
    for (int v = 0; v < hd; v++)
        for (int u = 0; u < wd; u++) {
            float z = zd[(size_t)v * (size_t)wd + (size_t)u];
            if (!(z > 0)) continue;
            double x = (u - Kd->cx) * ifx * z, y = (v - Kd->cy) * ify * z;
            double X = T[0] * x + T[1] * y + T[2] * z + T[3];
            double Y = T[4] * x + T[5] * y + T[6] * z + T[7];
            double Z = T[8] * x + T[9] * y + T[10] * z + T[11];
            if (Z <= 1e-6) continue;
            double uc = Kc->fx * X / Z + Kc->cx, vc = Kc->fy * Y / Z + Kc->cy;
            if (!(uc > -wc && uc < 2.0 * wc && vc > -hc && vc < 2.0 * hc)) continue;   /* also NaN */
            /* half the footprint, widened a little so that neighbours on a slanted surface leave no gap;
               at most 16 pixels (a depth pixel right in front of the colour camera) */
            double hx = fmin(0.6 * sx * z / Z + 0.05, 16.0), hy = fmin(0.6 * sy * z / Z + 0.05, 16.0);
            int x0 = (int)ceil(uc - hx), x1 = (int)floor(uc + hx);
            int y0 = (int)ceil(vc - hy), y1 = (int)floor(vc + hy);
            if (x1 < x0) x0 = x1 = (int)floor(uc + 0.5);
            if (y1 < y0) y0 = y1 = (int)floor(vc + 0.5);
            if (x1 < 0 || y1 < 0 || x0 >= wc || y0 >= hc) continue;
            if (x0 < 0) x0 = 0;
            if (y0 < 0) y0 = 0;
            if (x1 >= wc) x1 = wc - 1;
            if (y1 >= hc) y1 = hc - 1;
            float zc = (float)Z;
            for (int yy = y0; yy <= y1; yy++)
                for (int xx = x0; xx <= x1; xx++) {
                    float *o = &out[(size_t)yy * (size_t)wc + (size_t)xx];
                    if (*o == 0 || zc < *o) *o = zc;
                }
        }
}
