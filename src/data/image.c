/* Image buffers and the PNG / PGM codecs (libpng classic API; 16-bit samples
 * are big-endian in both formats and host order in memory). */
#include "sooc3d/image.h"
#include "data_impl.h"

#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <errno.h>
#include <sys/stat.h>

const char *sooc_pixfmt_name(sooc_pixfmt f) {
    switch (f) {
    case SOOC_PIX_GRAY8: return "gray8";
    case SOOC_PIX_GRAY16: return "gray16";
    case SOOC_PIX_RGB8: return "rgb8";
    default: return "none";
    }
}

int sooc_pixfmt_bytes(sooc_pixfmt f) {
    switch (f) {
    case SOOC_PIX_GRAY8: return 1;
    case SOOC_PIX_GRAY16: return 2;
    case SOOC_PIX_RGB8: return 3;
    default: return 0;
    }
}

sooc_status sooc_image_alloc(sooc_image *img, int w, int h, sooc_pixfmt fmt) {
    int bpp = sooc_pixfmt_bytes(fmt);
    if (w <= 0 || h <= 0 || w > 32768 || h > 32768 || bpp == 0)
        return sooc_seterr(SOOC_EINVAL, "image size %dx%d / format %s out of range", w, h,
                           sooc_pixfmt_name(fmt));
    size_t n = (size_t)w * (size_t)h * (size_t)bpp;
    if (img->data && img->width == w && img->height == h && img->fmt == fmt) {
        memset(img->data, 0, n);
        return SOOC_OK;
    }
    sooc_free(img->data);
    img->data = sooc_calloc(n, 1);
    if (!img->data) {
        memset(img, 0, sizeof *img);
        return SOOC_ENOMEM;
    }
    img->width = w;
    img->height = h;
    img->fmt = fmt;
    return SOOC_OK;
}

void sooc_image_free(sooc_image *img) {
    if (!img) return;
    sooc_free(img->data);
    memset(img, 0, sizeof *img);
}

sooc_status sooc_image_copy(sooc_image *dst, const sooc_image *src) {
    if (dst == src) return SOOC_OK;
    sooc_status s = sooc_image_alloc(dst, src->width, src->height, src->fmt);
    if (s) return s;
    memcpy(dst->data, src->data,
           (size_t)src->width * (size_t)src->height * (size_t)sooc_pixfmt_bytes(src->fmt));
    return SOOC_OK;
}

/* Reader size limits (image.h): checked on the header, before allocating. */
static sooc_status check_read_size(const char *path, const char *what, size_t w, size_t h, size_t bpp) {
    if (w > SOOC_IMAGE_READ_MAX_DIM || h > SOOC_IMAGE_READ_MAX_DIM)
        return sooc_seterr(SOOC_EFORMAT, "%s: %s of %zux%zu is larger than the %dx%d limit", path, what, w,
                           h, SOOC_IMAGE_READ_MAX_DIM, SOOC_IMAGE_READ_MAX_DIM);
    if (w * h * bpp > SOOC_IMAGE_READ_MAX_BYTES)
        return sooc_seterr(SOOC_EFORMAT, "%s: %s of %zux%zu needs %zu MiB, more than the %zu MiB limit", path,
                           what, w, h, (w * h * bpp) >> 20, SOOC_IMAGE_READ_MAX_BYTES >> 20);
    return SOOC_OK;
}

/* ------------------------------------------------------------------ PNG */

typedef struct png_err_ctx {
    char msg[256];
} png_err_ctx;

static void png_err_cb(png_structp png, png_const_charp msg) {
    png_err_ctx *e = png_get_error_ptr(png);
    if (e) snprintf(e->msg, sizeof e->msg, "%s", msg);
    png_longjmp(png, 1);
}
static void png_warn_cb(png_structp png, png_const_charp msg) { (void)png; (void)msg; }

static int host_is_le(void) {
    const uint16_t one = 1;
    return *(const uint8_t *)&one == 1;
}

/* Open `path`, check the signature. Returns FILE* or NULL with error set. */
static FILE *png_open(const char *path, sooc_status *st) {
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        *st = sooc_seterr(errno == ENOENT ? SOOC_ENOTFOUND : SOOC_EIO, "%s: cannot open: %s", path,
                          strerror(errno));
        return NULL;
    }
    unsigned char sig[8];
    if (fread(sig, 1, 8, fp) != 8 || png_sig_cmp(sig, 0, 8)) {
        fclose(fp);
        *st = sooc_seterr(SOOC_EFORMAT, "%s: not a PNG file", path);
        return NULL;
    }
    return fp;
}

static sooc_status png_read_impl(const char *path, sooc_image *out, int header_only, int *pw,
                                 int *ph, sooc_pixfmt *pfmt) {
    sooc_status st = SOOC_OK;
    FILE *fp = png_open(path, &st);
    if (!fp) return st;
    png_err_ctx ectx = {{0}};
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &ectx, png_err_cb, png_warn_cb);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    png_bytep *volatile rows = NULL; /* volatile: set after setjmp, freed after a longjmp */
    if (!png || !info) {
        if (png) png_destroy_read_struct(&png, NULL, NULL);
        fclose(fp);
        return sooc_seterr(SOOC_ENOMEM, "%s: libpng init failed", path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        free(rows);
        return sooc_seterr(SOOC_EFORMAT, "%s: corrupt PNG: %s", path, ectx.msg);
    }
    png_init_io(png, fp);
    png_set_sig_bytes(png, 8);
    png_set_user_limits(png, 32768, 32768);
    png_read_info(png, info);
    png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
    int depth = png_get_bit_depth(png, info), ctype = png_get_color_type(png, info);
    sooc_pixfmt fmt;
    if (ctype == PNG_COLOR_TYPE_GRAY || ctype == PNG_COLOR_TYPE_GRAY_ALPHA)
        fmt = depth == 16 ? SOOC_PIX_GRAY16 : SOOC_PIX_GRAY8;
    else
        fmt = SOOC_PIX_RGB8;
    /* Bound the decoded size before allocating: by the reader limits, and by
     * what the file can hold (deflate expands at most ~1032:1 and every pixel
     * takes at least one bit of the inflated stream), so a tiny file cannot
     * claim a huge image. */
    struct stat sb;
    size_t fsize = fstat(fileno(fp), &sb) == 0 && sb.st_size > 0 ? (size_t)sb.st_size : 0;
    st = check_read_size(path, "PNG", w, h, (size_t)sooc_pixfmt_bytes(fmt));
    if (!st && (size_t)w * h > (size_t)8 * 1100 * (fsize + 1024))
        st = sooc_seterr(SOOC_EFORMAT, "%s: corrupt PNG: %ux%u pixels cannot fit in a %zu-byte file", path,
                         (unsigned)w, (unsigned)h, fsize);
    if (st) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        return st;
    }
    if (pw) *pw = (int)w;
    if (ph) *ph = (int)h;
    if (pfmt) *pfmt = fmt;
    if (header_only) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        return SOOC_OK;
    }
    if (ctype == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (ctype == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_strip_alpha(png);
    if (ctype & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(png);
    if (fmt == SOOC_PIX_RGB8 && depth == 16) png_set_strip_16(png);
    if (fmt == SOOC_PIX_GRAY16 && host_is_le()) png_set_swap(png); /* PNG is big-endian */
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    size_t rowbytes = png_get_rowbytes(png, info);
    size_t bpp = (size_t)sooc_pixfmt_bytes(fmt);
    if (rowbytes != (size_t)w * bpp) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        return sooc_seterr(SOOC_EFORMAT, "%s: unsupported PNG layout (row %zu bytes for %u px)", path,
                           rowbytes, (unsigned)w);
    }
    st = sooc_image_alloc(out, (int)w, (int)h, fmt);
    if (st) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        return sooc_adderr(st, "%s", path);
    }
    rows = malloc(sizeof(png_bytep) * h);
    if (!rows) png_error(png, "out of memory");
    for (png_uint_32 y = 0; y < h; y++) rows[y] = (png_bytep)out->data + (size_t)y * rowbytes;
    png_read_image(png, rows);
    png_read_end(png, NULL);
    free(rows);
    png_destroy_read_struct(&png, &info, NULL);
    fclose(fp);
    return SOOC_OK;
}

sooc_status sooc_png_read(const char *path, sooc_image *out) {
    return png_read_impl(path, out, 0, NULL, NULL, NULL);
}

sooc_status sooc_png_info(const char *path, int *w, int *h, sooc_pixfmt *fmt) {
    return png_read_impl(path, NULL, 1, w, h, fmt);
}

typedef struct membuf {
    unsigned char *p;
    size_t n, cap;
    int oom;
} membuf;

static void png_mem_write(png_structp png, png_bytep data, png_size_t n) {
    membuf *m = png_get_io_ptr(png);
    if (m->oom) return;
    if (m->n + n > m->cap) {
        size_t cap = m->cap ? m->cap * 2 : 65536;
        while (cap < m->n + n) cap *= 2;
        unsigned char *q = sooc_realloc(m->p, cap);
        if (!q) { m->oom = 1; return; }
        m->p = q;
        m->cap = cap;
    }
    memcpy(m->p + m->n, data, n);
    m->n += n;
}
static void png_mem_flush(png_structp png) { (void)png; }

sooc_status sooc_png_encode(const sooc_image *img, int level, void **out, size_t *n) {
    *out = NULL;
    *n = 0;
    if (!img || !img->data || sooc_pixfmt_bytes(img->fmt) == 0)
        return sooc_seterr(SOOC_EINVAL, "png encode: empty image");
    membuf m = {0};
    png_err_ctx ectx = {{0}};
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ectx, png_err_cb, png_warn_cb);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    png_bytep *volatile rows = NULL; /* volatile: set after setjmp, freed after a longjmp */
    if (!png || !info) {
        if (png) png_destroy_write_struct(&png, NULL);
        return sooc_seterr(SOOC_ENOMEM, "png encode: libpng init failed");
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        free(rows);
        sooc_free(m.p);
        return sooc_seterr(SOOC_EIO, "png encode: %s", ectx.msg);
    }
    png_set_write_fn(png, &m, png_mem_write, png_mem_flush);
    int ctype = img->fmt == SOOC_PIX_RGB8 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY;
    int depth = img->fmt == SOOC_PIX_GRAY16 ? 16 : 8;
    png_set_IHDR(png, info, (png_uint_32)img->width, (png_uint_32)img->height, depth, ctype,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, level < 0 || level > 9 ? 6 : level);
    png_write_info(png, info);
    if (depth == 16 && host_is_le()) png_set_swap(png);
    size_t rowbytes = (size_t)img->width * (size_t)sooc_pixfmt_bytes(img->fmt);
    rows = malloc(sizeof(png_bytep) * (size_t)img->height);
    if (!rows) png_error(png, "out of memory");
    for (int y = 0; y < img->height; y++) rows[y] = (png_bytep)img->data + (size_t)y * rowbytes;
    png_write_image(png, rows);
    png_write_end(png, NULL);
    free(rows);
    png_destroy_write_struct(&png, &info);
    if (m.oom) {
        sooc_free(m.p);
        return sooc_seterr(SOOC_ENOMEM, "png encode: out of memory");
    }
    *out = m.p;
    *n = m.n;
    return SOOC_OK;
}

/* Write to "<path>.tmp" and rename over path: readers never see a partial
 * file. No fsync (datasets write thousands of small files; a crash may lose
 * recent files but never leaves a truncated one under the final name). */
sooc_status sooc_data_write_file(const char *path, const void *buf, size_t n) {
    char tmp[4200];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp)
        return sooc_seterr(SOOC_EINVAL, "%s: path too long", path);
    FILE *fp = fopen(tmp, "wb");
    if (!fp) return sooc_seterr(SOOC_EIO, "%s: cannot create: %s", tmp, strerror(errno));
    size_t w = fwrite(buf, 1, n, fp);
    int bad = w != n || fflush(fp) != 0;
    if (fclose(fp) != 0) bad = 1;
    if (bad || rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        return sooc_seterr(SOOC_EIO, "%s: write failed: %s", path, strerror(e));
    }
    return SOOC_OK;
}

sooc_status sooc_png_write(const char *path, const sooc_image *img, int level) {
    void *buf;
    size_t n;
    sooc_status s = sooc_png_encode(img, level, &buf, &n);
    if (s) return sooc_adderr(s, "%s", path);
    s = sooc_data_write_file(path, buf, n);
    sooc_free(buf);
    return s;
}

/* ------------------------------------------------------------------ PGM */

/* Read one header token (skipping whitespace and # comments). */
static int pgm_token(const unsigned char *b, size_t n, size_t *pos, long *val) {
    size_t i = *pos;
    for (;;) {
        while (i < n && (b[i] == ' ' || b[i] == '\t' || b[i] == '\n' || b[i] == '\r')) i++;
        if (i < n && b[i] == '#') {
            while (i < n && b[i] != '\n') i++;
            continue;
        }
        break;
    }
    if (i >= n || b[i] < '0' || b[i] > '9') return 0;
    long v = 0;
    while (i < n && b[i] >= '0' && b[i] <= '9') {
        v = v * 10 + (b[i] - '0');
        if (v > 100000000L) return 0;
        i++;
    }
    *val = v;
    *pos = i;
    return 1;
}

sooc_status sooc_pgm_read(const char *path, sooc_image *out) {
    void *buf;
    size_t n;
    sooc_status s = sooc_file_read_all(path, (size_t)1 << 31, &buf, &n);
    if (s) return s;
    const unsigned char *b = buf;
    if (n < 2 || b[0] != 'P' || (b[1] != '5' && b[1] != '2')) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EFORMAT, "%s: not a PGM (P5/P2) file", path);
    }
    int ascii = b[1] == '2';
    size_t pos = 2;
    long w, h, maxval;
    if (!pgm_token(b, n, &pos, &w) || !pgm_token(b, n, &pos, &h) || !pgm_token(b, n, &pos, &maxval) ||
        w <= 0 || h <= 0 || w > 32768 || h > 32768 || maxval <= 0 || maxval > 65535) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EFORMAT, "%s: bad PGM header", path);
    }
    sooc_pixfmt fmt = maxval > 255 ? SOOC_PIX_GRAY16 : SOOC_PIX_GRAY8;
    size_t np = (size_t)w * (size_t)h, bpp = fmt == SOOC_PIX_GRAY16 ? 2 : 1;
    s = check_read_size(path, "PGM", (size_t)w, (size_t)h, bpp);
    if (s) { sooc_free(buf); return s; }
    /* Check the data length against the header before allocating: binary
     * needs np * bpp bytes after the single whitespace byte; ASCII at least a
     * separator and a digit per sample. */
    size_t need = ascii ? 2 * np : 1 + np * bpp, have = n - pos;
    if (have < need) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EFORMAT, "%s: truncated PGM (%ldx%ld needs %zu bytes after the header, %zu present)",
                           path, w, h, need, have);
    }
    s = sooc_image_alloc(out, (int)w, (int)h, fmt);
    if (s) { sooc_free(buf); return sooc_adderr(s, "%s", path); }
    if (ascii) {
        for (size_t i = 0; i < np; i++) {
            long v;
            if (!pgm_token(b, n, &pos, &v) || v > maxval) {
                sooc_free(buf);
                return sooc_seterr(SOOC_EFORMAT, "%s: bad or missing sample %zu", path, i);
            }
            if (fmt == SOOC_PIX_GRAY16) ((uint16_t *)out->data)[i] = (uint16_t)v;
            else ((uint8_t *)out->data)[i] = (uint8_t)v;
        }
    } else {
        pos++; /* exactly one whitespace byte after maxval (length checked above) */
        if (fmt == SOOC_PIX_GRAY16) {
            uint16_t *d = out->data;
            for (size_t i = 0; i < np; i++)
                d[i] = (uint16_t)((b[pos + 2 * i] << 8) | b[pos + 2 * i + 1]); /* big-endian */
        } else {
            memcpy(out->data, b + pos, np);
        }
    }
    sooc_free(buf);
    return SOOC_OK;
}

sooc_status sooc_pgm_write(const char *path, const sooc_image *img) {
    if (!img->data || (img->fmt != SOOC_PIX_GRAY8 && img->fmt != SOOC_PIX_GRAY16))
        return sooc_seterr(SOOC_EINVAL, "%s: PGM needs a gray8 or gray16 image", path);
    char hdr[64];
    int hl = snprintf(hdr, sizeof hdr, "P5\n%d %d\n%d\n", img->width, img->height,
                      img->fmt == SOOC_PIX_GRAY16 ? 65535 : 255);
    size_t np = (size_t)img->width * (size_t)img->height;
    size_t nd = np * (img->fmt == SOOC_PIX_GRAY16 ? 2 : 1);
    unsigned char *b = sooc_malloc((size_t)hl + nd);
    if (!b) return SOOC_ENOMEM;
    memcpy(b, hdr, (size_t)hl);
    if (img->fmt == SOOC_PIX_GRAY16) {
        const uint16_t *d = img->data;
        for (size_t i = 0; i < np; i++) {
            b[hl + 2 * i] = (unsigned char)(d[i] >> 8);
            b[hl + 2 * i + 1] = (unsigned char)(d[i] & 0xff);
        }
    } else {
        memcpy(b + hl, img->data, np);
    }
    sooc_status s = sooc_data_write_file(path, b, (size_t)hl + nd);
    sooc_free(b);
    return s;
}

sooc_status sooc_image_read(const char *path, sooc_image *out) {
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return sooc_seterr(errno == ENOENT ? SOOC_ENOTFOUND : SOOC_EIO, "%s: cannot open: %s", path,
                           strerror(errno));
    unsigned char sig[8] = {0};
    size_t got = fread(sig, 1, 8, fp);
    fclose(fp);
    if (got >= 8 && !png_sig_cmp(sig, 0, 8)) return sooc_png_read(path, out);
    if (got >= 2 && sig[0] == 'P' && (sig[1] == '5' || sig[1] == '2')) return sooc_pgm_read(path, out);
    if (got >= 3 && sig[0] == 0xFF && sig[1] == 0xD8 && sig[2] == 0xFF)
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: JPEG is not supported; convert to PNG", path);
    return sooc_seterr(SOOC_EFORMAT, "%s: unknown image format (expected PNG or PGM)", path);
}
