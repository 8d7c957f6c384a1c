/* The message index the container readers (bag.c, mcap.c) build through
 * logs_impl.h: positioned reads, channels, chunks and entries, buffer growth,
 * and the chunk decompression (lz4, zstd, bz2). */
#include "logs_impl.h"

#include <bzlib.h>
#include <errno.h>
#include <fcntl.h>
#include <lz4.h>
#include <lz4frame.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

const char *sooc_logs_comp_name(int comp) {
    switch (comp) {
    case LOGS_COMP_LZ4: return "lz4";
    case LOGS_COMP_BZ2: return "bz2";
    case LOGS_COMP_ZSTD: return "zstd";
    default: return "none";
    }
}

int sooc_logs_comp_parse(const char *s, size_t n) {
    if (n == 0 || (n == 4 && !memcmp(s, "none", 4))) return LOGS_COMP_NONE;
    if (n == 3 && !memcmp(s, "lz4", 3)) return LOGS_COMP_LZ4;
    if (n == 3 && !memcmp(s, "bz2", 3)) return LOGS_COMP_BZ2;
    if (n == 4 && !memcmp(s, "zstd", 4)) return LOGS_COMP_ZSTD;
    return -1;
}

sooc_status sooc_logs_pread(sooc_logfile *lf, uint64_t off, void *buf, size_t n, const char *what) {
    if (off > lf->size || n > lf->size - off)
        return sooc_seterr(SOOC_EFORMAT,
                           "%s: offset %llu: %s of %zu bytes runs past the end of the file (%llu bytes): the file "
                           "is truncated",
                           lf->path, (unsigned long long)off, what, n, (unsigned long long)lf->size);
    size_t got = 0;
    while (got < n) {
        ssize_t r = pread(lf->fd, (uint8_t *)buf + got, n - got, (off_t)(off + got));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0)
            return sooc_seterr(SOOC_EIO, "%s: offset %llu: read failed: %s", lf->path,
                               (unsigned long long)(off + got), r < 0 ? strerror(errno) : "unexpected end of file");
        got += (size_t)r;
    }
    return SOOC_OK;
}

sooc_status sooc_logs_chunk_cut(const sooc_logfile *lf, uint64_t where, size_t i, size_t n) {
    return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: record at chunk byte %zu of %zu is cut short (corrupt chunk)",
                       lf->path, (unsigned long long)where, i, n);
}

sooc_status sooc_logs_reserve(uint8_t **buf, size_t *cap, size_t n) {
    if (*cap >= n && *buf) return SOOC_OK;
    /* twice the old size, or n when that is more: a chunk that claims a large size gets
     * that size, not the next power of two above it */
    size_t c = *cap > SIZE_MAX / 2 ? n : *cap * 2;
    if (c < n) c = n;
    if (c < 4096) c = 4096;
    uint8_t *p = sooc_realloc(*buf, c);
    if (!p) return sooc_seterr(SOOC_ENOMEM, "out of memory (%zu bytes)", c);
    *buf = p;
    *cap = c;
    return SOOC_OK;
}

char *sooc_logs_dupn(const char *s, size_t n) {
    char *d = sooc_malloc(n + 1);
    if (!d) return NULL;
    if (n) memcpy(d, s, n);
    d[n] = 0;
    return d;
}

sooc_status sooc_logs_grow(void **p, int64_t *cap, int64_t need, size_t elem, const char *path) {
    if (need <= *cap) return SOOC_OK;
    int64_t c = *cap ? *cap : 16;
    while (c < need) c *= 2;
    void *q = sooc_realloc(*p, elem * (size_t)c);
    if (!q) return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", path);
    *p = q;
    *cap = c;
    return SOOC_OK;
}

sooc_status sooc_logs_add_channel(sooc_logfile *lf, uint32_t file_id, const char *topic, size_t ntopic, const char *type,
                             size_t ntype, const char *encoding, const char *definition, size_t ndef, int schema,
                             int *index) {
    sooc_status st = sooc_logs_grow((void **)&lf->ch, &lf->capch, lf->nch + 1, sizeof *lf->ch, lf->path);
    if (st) return st;
    sooc_logs_chan *c = &lf->ch[lf->nch];
    memset(c, 0, sizeof *c);
    c->file_id = file_id;
    c->schema = schema;
    c->topic = sooc_logs_dupn(topic, ntopic);
    c->type = sooc_logs_dupn(type, ntype);
    c->encoding = sooc_logs_dupn(encoding, strlen(encoding));
    c->definition = sooc_logs_dupn(definition ? definition : "", definition ? ndef : 0);
    if (!c->topic || !c->type || !c->encoding || !c->definition) {
        sooc_free(c->topic);
        sooc_free(c->type);
        sooc_free(c->encoding);
        sooc_free(c->definition);
        return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", lf->path);
    }
    if (index) *index = lf->nch;
    lf->nch++;
    return SOOC_OK;
}

int sooc_logs_find_channel(const sooc_logfile *lf, uint32_t file_id) {
    for (int i = 0; i < lf->nch; i++)
        if (lf->ch[i].file_id == file_id) return i;
    return -1;
}

sooc_status sooc_logs_add_chunk(sooc_logfile *lf, const sooc_logs_chunk *c, int32_t *index) {
    /* the sizes a chunk header may claim before anything is allocated for it */
    if (c->usize > LOGS_MAX_RECORD || (c->comp == LOGS_COMP_NONE && c->usize != c->csize) ||
        (c->comp == LOGS_COMP_LZ4 && c->usize > 256 * c->csize + 1024))
        return sooc_seterr(SOOC_EFORMAT,
                           "%s: offset %llu: chunk of %llu bytes (%s) claims %llu bytes uncompressed, which it cannot "
                           "hold (corrupt header)",
                           lf->path, (unsigned long long)c->pos, (unsigned long long)c->csize, sooc_logs_comp_name(c->comp),
                           (unsigned long long)c->usize);
    sooc_status st = sooc_logs_grow((void **)&lf->chunks, &lf->capchunks, lf->nchunks + 1, sizeof *lf->chunks, lf->path);
    if (st) return st;
    if (lf->nchunks >= INT32_MAX) return sooc_seterr(SOOC_EFORMAT, "%s: too many chunks", lf->path);
    lf->chunks[lf->nchunks] = *c;
    lf->comp_seen |= 1u << c->comp;
    *index = (int32_t)lf->nchunks++;
    return SOOC_OK;
}

sooc_status sooc_logs_add_entry(sooc_logfile *lf, int64_t t, uint64_t off, int32_t chunk, int32_t ch) {
    sooc_status st = sooc_logs_grow((void **)&lf->e, &lf->cape, lf->ne + 1, sizeof *lf->e, lf->path);
    if (st) return st;
    lf->e[lf->ne++] = (sooc_logs_entry){t, off, chunk, ch};
    return SOOC_OK;
}

/* ------------------------------------------------------- decompression */

/* Decompress n bytes of method comp into exactly dn bytes. ctx names the place. */
static sooc_status sooc_logs_decompress(int comp, const uint8_t *src, size_t n, uint8_t *dst, size_t dn, const char *path,
                            uint64_t off) {
    unsigned long long o = (unsigned long long)off;
    switch (comp) {
    case LOGS_COMP_NONE:
        if (n != dn)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: uncompressed chunk holds %zu bytes, its header says %zu",
                               path, o, n, dn);
        memcpy(dst, src, n);
        return SOOC_OK;
    case LOGS_COMP_LZ4: {
        if (n >= 4 && logs_u32(src) == 0x184D2204u) {   /* LZ4 frame */
            LZ4F_dctx *dc = NULL;
            if (LZ4F_isError(LZ4F_createDecompressionContext(&dc, LZ4F_VERSION)))
                return sooc_seterr(SOOC_ENOMEM, "%s: lz4: cannot create a context", path);
            size_t in = 0, outp = 0, r = 1;
            while (in < n && r != 0) {
                size_t si = n - in, so = dn - outp;
                r = LZ4F_decompress(dc, dst + outp, &so, src + in, &si, NULL);
                if (LZ4F_isError(r)) {
                    LZ4F_freeDecompressionContext(dc);
                    return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: corrupt LZ4 chunk: %s", path, o,
                                       LZ4F_getErrorName(r));
                }
                in += si;
                outp += so;
                if (si == 0 && so == 0) break;
            }
            LZ4F_freeDecompressionContext(dc);
            if (outp != dn || r != 0)
                return sooc_seterr(SOOC_EFORMAT,
                                   "%s: offset %llu: LZ4 chunk decompresses to %zu bytes%s, its header says %zu",
                                   path, o, outp, r ? " (stream incomplete)" : "", dn);
            return SOOC_OK;
        }
        if (n > INT32_MAX || dn > INT32_MAX)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: LZ4 block too large", path, o);
        int r = LZ4_decompress_safe((const char *)src, (char *)dst, (int)n, (int)dn);
        if (r < 0 || (size_t)r != dn)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: corrupt LZ4 chunk (block decode %d of %zu bytes)", path,
                               o, r, dn);
        return SOOC_OK;
    }
    case LOGS_COMP_BZ2: {
        if (n > UINT32_MAX || dn > UINT32_MAX)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: bz2 chunk too large", path, o);
        unsigned int got = (unsigned int)dn;
        int r = BZ2_bzBuffToBuffDecompress((char *)dst, &got, (char *)(uintptr_t)src, (unsigned int)n, 0, 0);
        if (r != BZ_OK || got != dn)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: corrupt bz2 chunk (bzip2 error %d, %u of %zu bytes)",
                               path, o, r, got, dn);
        return SOOC_OK;
    }
    case LOGS_COMP_ZSTD: {
        size_t r = ZSTD_decompress(dst, dn, src, n);
        if (ZSTD_isError(r))
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: corrupt zstd chunk: %s", path, o, ZSTD_getErrorName(r));
        if (r != dn)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: zstd chunk decompresses to %zu bytes, its header says %zu",
                               path, o, r, dn);
        return SOOC_OK;
    }
    default:
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: offset %llu: unknown chunk compression", path, o);
    }
}

sooc_status sooc_logs_chunk_data(sooc_logfile *lf, int32_t c, const uint8_t **data, size_t *n) {
    if (c < 0 || c >= lf->nchunks) return sooc_seterr(SOOC_EINVAL, "%s: no chunk %d", lf->path, (int)c);
    lf->clock++;
    for (int s = 0; s < 2; s++)
        if (lf->slot[s].chunk == c && lf->slot[s].buf) {
            lf->slot[s].stamp = lf->clock;
            *data = lf->slot[s].buf;
            *n = (size_t)lf->chunks[c].usize;
            return SOOC_OK;
        }
    sooc_logs_slot *sl = lf->slot[0].stamp <= lf->slot[1].stamp ? &lf->slot[0] : &lf->slot[1];
    const sooc_logs_chunk *k = &lf->chunks[c];
    sl->chunk = -1;
    if (k->comp == LOGS_COMP_NONE && k->csize != k->usize)   /* before the buffer: csize lies in the file */
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: uncompressed chunk holds %llu bytes, its header says %llu",
                           lf->path, (unsigned long long)k->pos, (unsigned long long)k->csize,
                           (unsigned long long)k->usize);
    sooc_status st = sooc_logs_reserve(&sl->buf, &sl->cap, (size_t)k->usize + 1);
    if (st) return st;
    if (k->comp == LOGS_COMP_NONE) {
        st = sooc_logs_pread(lf, k->data_off, sl->buf, (size_t)k->usize, "chunk");
    } else {
        st = sooc_logs_reserve(&lf->raw, &lf->rawcap, (size_t)k->csize + 1);
        if (!st) st = sooc_logs_pread(lf, k->data_off, lf->raw, (size_t)k->csize, "chunk");
        if (!st) st = sooc_logs_decompress(k->comp, lf->raw, (size_t)k->csize, sl->buf, (size_t)k->usize, lf->path, k->pos);
    }
    if (st) return st;
    if (k->crc) {
        uint32_t got = sooc_crc32(0, sl->buf, (size_t)k->usize);
        if (got != k->crc)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: chunk CRC mismatch (stored 0x%08x, computed 0x%08x)",
                               lf->path, (unsigned long long)k->pos, k->crc, got);
    }
    sl->chunk = c;
    sl->stamp = lf->clock;
    *data = sl->buf;
    *n = (size_t)k->usize;
    return SOOC_OK;
}
