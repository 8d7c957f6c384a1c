/* Image buffers and the PNG / PGM / JPEG codecs (libpng classic API,
 * libjpeg-turbo's libjpeg API; 16-bit samples are big-endian in PNG and PGM
 * and host order in memory). */
#include "sooc3d/core.h"

#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <jpeglib.h>
#include <jerror.h>
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

/* Reader size limits (core.h): checked on the header, before allocating. */
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

/* Bytes of a PNG held in memory (sooc_png_decode). */
typedef struct png_mem_src {
    const unsigned char *p;
    size_t n, pos;
} png_mem_src;

static void png_mem_read(png_structp png, png_bytep data, png_size_t n) {
    png_mem_src *m = png_get_io_ptr(png);
    if (n > m->n - m->pos) png_error(png, "unexpected end of data");
    memcpy(data, m->p + m->pos, n);
    m->pos += n;
}

/* Decode from the open file fp (after its signature) or, when fp is NULL,
 * from mem (path names it in messages). */
static sooc_status png_decode_impl(const char *path, FILE *fp, png_mem_src *mem, sooc_image *out, int header_only,
                                   int *pw, int *ph, sooc_pixfmt *pfmt) {
    sooc_status st = SOOC_OK;
    png_err_ctx ectx = {{0}};
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &ectx, png_err_cb, png_warn_cb);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    png_bytep *volatile rows = NULL; /* volatile: set after setjmp, freed after a longjmp */
    if (!png || !info) {
        if (png) png_destroy_read_struct(&png, NULL, NULL);
        if (fp) fclose(fp);
        return sooc_seterr(SOOC_ENOMEM, "%s: libpng init failed", path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, NULL);
        if (fp) fclose(fp);
        free(rows);
        return sooc_seterr(SOOC_EFORMAT, "%s: corrupt PNG: %s", path, ectx.msg);
    }
    if (fp) png_init_io(png, fp);
    else png_set_read_fn(png, mem, png_mem_read);
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
    size_t fsize = !fp ? mem->n : fstat(fileno(fp), &sb) == 0 && sb.st_size > 0 ? (size_t)sb.st_size : 0;
    st = check_read_size(path, "PNG", w, h, (size_t)sooc_pixfmt_bytes(fmt));
    if (!st && (size_t)w * h > (size_t)8 * 1100 * (fsize + 1024))
        st = sooc_seterr(SOOC_EFORMAT, "%s: corrupt PNG: %ux%u pixels cannot fit in a %zu-byte file", path,
                         (unsigned)w, (unsigned)h, fsize);
    if (st) {
        png_destroy_read_struct(&png, &info, NULL);
        if (fp) fclose(fp);
        return st;
    }
    if (pw) *pw = (int)w;
    if (ph) *ph = (int)h;
    if (pfmt) *pfmt = fmt;
    if (header_only) {
        png_destroy_read_struct(&png, &info, NULL);
        if (fp) fclose(fp);
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
        if (fp) fclose(fp);
        return sooc_seterr(SOOC_EFORMAT, "%s: unsupported PNG layout (row %zu bytes for %u px)", path,
                           rowbytes, (unsigned)w);
    }
    st = sooc_image_alloc(out, (int)w, (int)h, fmt);
    if (st) {
        png_destroy_read_struct(&png, &info, NULL);
        if (fp) fclose(fp);
        return sooc_adderr(st, "%s", path);
    }
    rows = malloc(sizeof(png_bytep) * h);
    if (!rows) png_error(png, "out of memory");
    for (png_uint_32 y = 0; y < h; y++) rows[y] = (png_bytep)out->data + (size_t)y * rowbytes;
    png_read_image(png, rows);
    png_read_end(png, NULL);
    free(rows);
    png_destroy_read_struct(&png, &info, NULL);
    if (fp) fclose(fp);
    return SOOC_OK;
}

static sooc_status png_read_impl(const char *path, sooc_image *out, int header_only, int *pw, int *ph,
                                 sooc_pixfmt *pfmt) {
    sooc_status st = SOOC_OK;
    FILE *fp = png_open(path, &st);
    return fp ? png_decode_impl(path, fp, NULL, out, header_only, pw, ph, pfmt) : st;
}

sooc_status sooc_png_read(const char *path, sooc_image *out) {
    return png_read_impl(path, out, 0, NULL, NULL, NULL);
}

sooc_status sooc_png_info(const char *path, int *w, int *h, sooc_pixfmt *fmt) {
    return png_read_impl(path, NULL, 1, w, h, fmt);
}

sooc_status sooc_png_decode(const void *buf, size_t n, const char *name, sooc_image *out) {
    if (!name) name = "PNG data";
    if (!buf || n < 8 || png_sig_cmp((png_const_bytep)buf, 0, 8))
        return sooc_seterr(SOOC_EFORMAT, "%s: not a PNG image", name);
    png_mem_src m = {buf, n, 8};
    return png_decode_impl(name, NULL, &m, out, 0, NULL, NULL, NULL);
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


sooc_status sooc_png_write(const char *path, const sooc_image *img, int level) {
    void *buf;
    size_t n;
    sooc_status s = sooc_png_encode(img, level, &buf, &n);
    if (s) return sooc_adderr(s, "%s", path);
    s = sooc_file_write_bulk(path, buf, n);
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
    sooc_status s = sooc_file_write_bulk(path, b, (size_t)hl + nd);
    sooc_free(b);
    return s;
}

/* ----------------------------------------------------------------- JPEG */

/* libjpeg reports errors through error_exit (must not return) and messages
 * through emit_message/output_message, which print to stderr by default. We
 * keep the text, never print, and longjmp back. Corrupt-data warnings
 * (truncation, bad Huffman codes, lost sync, bad progression) are errors too:
 * libjpeg would otherwise pad the image with grey and report success.
 * "Extraneous bytes before marker" (padding many webcams put before EOI in
 * MJPEG frames) is tolerated: the pixels are complete. */
typedef struct jpeg_err_ctx {
    struct jpeg_error_mgr pub;
    jmp_buf jb;
    char msg[JMSG_LENGTH_MAX];
    unsigned char *mem;      /* encoder: jpeg_mem_dest's buffer (libjpeg malloc), kept here across a longjmp */
    unsigned long msize;
} jpeg_err_ctx;

static void jpeg_err_exit(j_common_ptr c) {
    jpeg_err_ctx *e = (jpeg_err_ctx *)c->err;
    if (!e->msg[0]) (*c->err->format_message)(c, e->msg);
    longjmp(e->jb, 1);
}

static void jpeg_out_msg(j_common_ptr c) { (void)c; }

static void jpeg_emit(j_common_ptr c, int level) {
    if (level >= 0) return; /* trace messages */
    int code = c->err->msg_code;
    if (code == JWRN_JPEG_EOF || code == JWRN_HIT_MARKER || code == JWRN_MUST_RESYNC || code == JWRN_HUFF_BAD_CODE ||
        code == JWRN_NOT_SEQUENTIAL || code == JWRN_BOGUS_PROGRESSION || code == JWRN_TOO_MUCH_DATA)
        jpeg_err_exit(c);
    c->err->num_warnings++;
}

/* Progressive files can hold thousands of tiny scans (a CPU sink on hostile
 * input, libjpeg-turbo's advice for untrusted data): cap the scan count. */
#define JPEG_MAX_SCANS 500
static void jpeg_progress(j_common_ptr c) {
    if (c->is_decompressor && ((j_decompress_ptr)c)->input_scan_number > JPEG_MAX_SCANS) {
        jpeg_err_ctx *e = (jpeg_err_ctx *)c->err;
        snprintf(e->msg, sizeof e->msg, "more than %d progressive scans", JPEG_MAX_SCANS);
        longjmp(e->jb, 1);
    }
}

static void jpeg_err_init(jpeg_err_ctx *e) {
    memset(e, 0, sizeof *e);
    jpeg_std_error(&e->pub);
    e->pub.error_exit = jpeg_err_exit;
    e->pub.output_message = jpeg_out_msg;
    e->pub.emit_message = jpeg_emit;
}

/* Decode (or, with header_only, only size the image of) n bytes of JPEG. */
static sooc_status jpeg_decode_impl(const void *buf, size_t n, const char *name, sooc_image *out, int header_only,
                                    int *pw, int *ph, sooc_pixfmt *pfmt) {
    const unsigned char *b = buf;
    if (!buf || n < 4 || b[0] != 0xFF || b[1] != 0xD8 || b[2] != 0xFF)
        return sooc_seterr(SOOC_EFORMAT, "%s: not a JPEG file (no SOI marker)", name);
    if (n > (size_t)0xFFFFFFFFu) return sooc_seterr(SOOC_EFORMAT, "%s: JPEG larger than 4 GiB", name);
    struct jpeg_decompress_struct ci;
    jpeg_err_ctx err;
    struct jpeg_progress_mgr prog;
    jpeg_err_init(&err);
    memset(&ci, 0, sizeof ci);
    ci.err = &err.pub;
    volatile int created = 0;
    sooc_status st = SOOC_OK;
    if (setjmp(err.jb)) {
        if (created) jpeg_destroy_decompress(&ci);
        return sooc_seterr(SOOC_EFORMAT, "%s: corrupt JPEG: %s", name, err.msg[0] ? err.msg : "decoder error");
    }
    jpeg_create_decompress(&ci);
    created = 1;
    memset(&prog, 0, sizeof prog);
    prog.progress_monitor = jpeg_progress;
    ci.progress = &prog;
    ci.mem->max_memory_to_use = (long)(SOOC_IMAGE_READ_MAX_BYTES * 2); /* coefficient buffers of progressive files */
    jpeg_mem_src(&ci, b, (unsigned long)n);
    jpeg_read_header(&ci, TRUE);
    sooc_pixfmt fmt;
    if (ci.num_components == 1) {
        fmt = SOOC_PIX_GRAY8;
        ci.out_color_space = JCS_GRAYSCALE;
    } else if (ci.num_components == 3) {
        fmt = SOOC_PIX_RGB8;
        ci.out_color_space = JCS_RGB;
    } else {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "%s: JPEG with %d colour components (CMYK?) is not supported", name,
                         ci.num_components);
        jpeg_destroy_decompress(&ci);
        return st;
    }
    st = check_read_size(name, "JPEG", ci.image_width, ci.image_height, (size_t)sooc_pixfmt_bytes(fmt));
    if (st || header_only) {
        jpeg_destroy_decompress(&ci);
        if (!st) {
            if (pw) *pw = (int)ci.image_width;
            if (ph) *ph = (int)ci.image_height;
            if (pfmt) *pfmt = fmt;
        }
        return st;
    }
    ci.dct_method = JDCT_ISLOW; /* accurate and the same on every machine */
    jpeg_start_decompress(&ci);
    int w = (int)ci.output_width, h = (int)ci.output_height;
    if (ci.output_components != sooc_pixfmt_bytes(fmt)) {
        jpeg_destroy_decompress(&ci);
        return sooc_seterr(SOOC_EFORMAT, "%s: JPEG decodes to %d components, expected %d", name,
                           ci.output_components, sooc_pixfmt_bytes(fmt));
    }
    st = sooc_image_alloc(out, w, h, fmt);
    if (st) {
        jpeg_destroy_decompress(&ci);
        return sooc_adderr(st, "%s", name);
    }
    size_t stride = (size_t)w * (size_t)sooc_pixfmt_bytes(fmt);
    while (ci.output_scanline < ci.output_height) {
        JSAMPROW row = (JSAMPROW)((unsigned char *)out->data + (size_t)ci.output_scanline * stride);
        if (jpeg_read_scanlines(&ci, &row, 1) != 1) break; /* suspension cannot happen with a memory source */
    }
    if (ci.output_scanline < ci.output_height) {
        jpeg_destroy_decompress(&ci);
        return sooc_seterr(SOOC_EFORMAT, "%s: corrupt JPEG: %u of %d rows decoded", name, ci.output_scanline, h);
    }
    jpeg_finish_decompress(&ci);
    jpeg_destroy_decompress(&ci);
    if (pw) *pw = w;
    if (ph) *ph = h;
    if (pfmt) *pfmt = fmt;
    return SOOC_OK;
}

sooc_status sooc_jpeg_decode(const void *buf, size_t n, const char *name, sooc_image *out) {
    return jpeg_decode_impl(buf, n, name ? name : "JPEG", out, 0, NULL, NULL, NULL);
}

sooc_status sooc_jpeg_read(const char *path, sooc_image *out) {
    void *buf;
    size_t n;
    sooc_status s = sooc_file_read_all(path, (size_t)1 << 30, &buf, &n);
    if (s) return s;
    s = jpeg_decode_impl(buf, n, path, out, 0, NULL, NULL, NULL);
    sooc_free(buf);
    return s;
}

static sooc_status jpeg_encode_impl(const sooc_image *img, int quality, void **out, size_t *n);

sooc_status sooc_jpeg_encode(const sooc_image *img, int quality, void **out, size_t *n) {
    return jpeg_encode_impl(img, quality < 1 || quality > 100 ? 90 : quality, out, n);
}

static sooc_status jpeg_encode_impl(const sooc_image *img, int quality, void **out, size_t *n) {
    *out = NULL;
    *n = 0;
    if (!img || !img->data || (img->fmt != SOOC_PIX_RGB8 && img->fmt != SOOC_PIX_GRAY8))
        return sooc_seterr(SOOC_EINVAL, "JPEG encode: needs an rgb8 or gray8 image");
    struct jpeg_compress_struct ci;
    jpeg_err_ctx err;
    jpeg_err_init(&err);
    memset(&ci, 0, sizeof ci);
    ci.err = &err.pub;
    volatile int created = 0;
    if (setjmp(err.jb)) {
        if (created) jpeg_destroy_compress(&ci);
        free(err.mem);
        return sooc_seterr(SOOC_EINVAL, "JPEG encode: %s", err.msg);
    }
    jpeg_create_compress(&ci);
    created = 1;
    jpeg_mem_dest(&ci, &err.mem, &err.msize);
    ci.image_width = (JDIMENSION)img->width;
    ci.image_height = (JDIMENSION)img->height;
    ci.input_components = img->fmt == SOOC_PIX_RGB8 ? 3 : 1;
    ci.in_color_space = img->fmt == SOOC_PIX_RGB8 ? JCS_RGB : JCS_GRAYSCALE;
    jpeg_set_defaults(&ci);
    jpeg_set_quality(&ci, quality, TRUE);
    ci.dct_method = JDCT_ISLOW;
    jpeg_start_compress(&ci, TRUE);
    size_t stride = (size_t)img->width * (size_t)ci.input_components;
    while (ci.next_scanline < ci.image_height) {
        JSAMPROW row = (JSAMPROW)((unsigned char *)img->data + (size_t)ci.next_scanline * stride);
        jpeg_write_scanlines(&ci, &row, 1);
    }
    jpeg_finish_compress(&ci);
    jpeg_destroy_compress(&ci);
    void *copy = sooc_malloc(err.msize ? err.msize : 1);
    if (!copy) { free(err.mem); return SOOC_ENOMEM; }
    memcpy(copy, err.mem, err.msize);
    free(err.mem);
    *out = copy;
    *n = err.msize;
    return SOOC_OK;
}

sooc_status sooc_jpeg_write(const char *path, const sooc_image *img, int quality) {
    void *buf;
    size_t n;
    sooc_status s = sooc_jpeg_encode(img, quality, &buf, &n);
    if (s) return sooc_adderr(s, "%s", path);
    s = sooc_file_write_bulk(path, buf, n);
    sooc_free(buf);
    return s;
}

/* ------------------------------------------------------- by content */

/* Which codec a file's first bytes belong to: 1 PNG, 2 PGM, 3 JPEG, 0 none. */
static int sniff(const char *path, sooc_status *st) {
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        *st = sooc_seterr(errno == ENOENT ? SOOC_ENOTFOUND : SOOC_EIO, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    unsigned char sig[8] = {0};
    size_t got = fread(sig, 1, 8, fp);
    fclose(fp);
    if (got >= 8 && !png_sig_cmp(sig, 0, 8)) return 1;
    if (got >= 2 && sig[0] == 'P' && (sig[1] == '5' || sig[1] == '2')) return 2;
    if (got >= 3 && sig[0] == 0xFF && sig[1] == 0xD8 && sig[2] == 0xFF) return 3;
    *st = sooc_seterr(SOOC_EFORMAT, "%s: unknown image format (expected PNG, PGM or JPEG)", path);
    return 0;
}

sooc_status sooc_image_read(const char *path, sooc_image *out) {
    sooc_status st = SOOC_OK;
    switch (sniff(path, &st)) {
    case 1: return sooc_png_read(path, out);
    case 2: return sooc_pgm_read(path, out);
    case 3: return sooc_jpeg_read(path, out);
    default: return st;
    }
}

sooc_status sooc_image_info(const char *path, int *w, int *h, sooc_pixfmt *fmt) {
    sooc_status st = SOOC_OK;
    int k = sniff(path, &st);
    if (k == 1) return sooc_png_info(path, w, h, fmt);
    if (k == 3) {
        /* the header is near the start, but EXIF thumbnails can push it back: read up to 1 MiB */
        FILE *fp = fopen(path, "rb");
        if (!fp) return sooc_seterr(SOOC_EIO, "%s: cannot open: %s", path, strerror(errno));
        size_t cap = (size_t)1 << 20;
        unsigned char *b = sooc_malloc(cap);
        if (!b) { fclose(fp); return SOOC_ENOMEM; }
        size_t n = fread(b, 1, cap, fp);
        fclose(fp);
        /* a truncated stream is fine for the header: silence EOF by decoding only the header */
        st = jpeg_decode_impl(b, n, path, NULL, 1, w, h, fmt);
        sooc_free(b);
        return st;
    }
    if (k == 2) {
        sooc_image tmp = {0};
        st = sooc_pgm_read(path, &tmp);
        if (!st) {
            if (w) *w = tmp.width;
            if (h) *h = tmp.height;
            if (fmt) *fmt = tmp.fmt;
        }
        sooc_image_free(&tmp);
        return st;
    }
    return st;
}
