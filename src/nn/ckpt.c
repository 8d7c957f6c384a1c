/*
 * Checkpoint files (format in nn.h): header, view table, config blob,
 * trainer blob, parameter slab, optional Adam moments, CRC32.
 * The loader validates everything (size from stat, header fields against the
 * file size and the caller's layout, CRC over the whole file) before it
 * touches the caller's parameters, and never allocates from a size read from
 * the file without checking it against the real file size first.
 */
#include "nn_impl.h"
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

static const char CKPT_MAGIC[8] = {'S', 'O', 'O', 'C', 'N', 'N', 'C', 'K'};

typedef struct ckpt_header {
    char magic[8];
    uint32_t version, flags, n_views, reserved;
    uint64_t n_total, config_bytes, trainer_bytes;
    int64_t adam_t;
    uint64_t file_bytes;
} ckpt_header;

static size_t table_bytes(const sooc_nn_params *p) {
    size_t n = 0;
    for (int i = 0; i < p->n_views; i++)
        n += 4 + strlen(p->views[i].name) + 4 + 8 * (size_t)p->views[i].ndim + 8;
    return n;
}

static int host_little_endian(void) {
    uint32_t x = 1;
    unsigned char c;
    memcpy(&c, &x, 1);
    return c == 1;
}

sooc_status sooc_nn_ckpt_save(const char *path, const sooc_nn_params *p, const void *config,
                              size_t config_bytes, const void *trainer, size_t trainer_bytes,
                              int with_optimizer) {
    if (!host_little_endian())
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: big-endian hosts not supported", path);
    if (!p->w) return sooc_seterr(SOOC_EINVAL, "%s: params not allocated", path);
    if (config_bytes > SOOC_NN_CKPT_MAX_BLOB || trainer_bytes > SOOC_NN_CKPT_MAX_BLOB)
        return sooc_seterr(SOOC_EINVAL, "%s: config/trainer blob too large", path);
    ckpt_header h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, CKPT_MAGIC, 8);
    h.version = SOOC_NN_CKPT_VERSION;
    h.flags = with_optimizer ? 1u : 0u;
    h.n_views = (uint32_t)p->n_views;
    h.n_total = p->n_total;
    h.config_bytes = config_bytes;
    h.trainer_bytes = trainer_bytes;
    h.adam_t = p->adam_t;
    size_t slab = p->n_total * sizeof(float);
    h.file_bytes = sizeof h + table_bytes(p) + config_bytes + trainer_bytes +
                   slab * (with_optimizer ? 3 : 1) + 4;
    sooc_afile f;
    sooc_status s = sooc_afile_open(&f, path);
    if (s) return s;
    s = sooc_afile_write(&f, &h, sizeof h);
    for (int i = 0; i < p->n_views && !s; i++) {
        const sooc_nn_param_view *v = &p->views[i];
        uint32_t len = (uint32_t)strlen(v->name), nd = (uint32_t)v->ndim;
        uint64_t off = v->offset;
        s = sooc_afile_write(&f, &len, 4);
        if (!s) s = sooc_afile_write(&f, v->name, len);
        if (!s) s = sooc_afile_write(&f, &nd, 4);
        if (!s) s = sooc_afile_write(&f, v->shape, 8 * (size_t)v->ndim);
        if (!s) s = sooc_afile_write(&f, &off, 8);
    }
    if (!s && config_bytes) s = sooc_afile_write(&f, config, config_bytes);
    if (!s && trainer_bytes) s = sooc_afile_write(&f, trainer, trainer_bytes);
    if (!s) s = sooc_afile_write(&f, p->w, slab);
    if (!s && with_optimizer) s = sooc_afile_write(&f, p->m, slab);
    if (!s && with_optimizer) s = sooc_afile_write(&f, p->v, slab);
    if (!s) {
        uint32_t crc = f.crc;
        s = sooc_afile_write(&f, &crc, 4);
    }
    if (s) {
        sooc_afile_abort(&f);
        return sooc_adderr(s, "%s: checkpoint save", path);
    }
    return sooc_afile_commit(&f);
}

/* Reader state: the whole file is checked (size, CRC) on open. */
typedef struct ckpt_reader {
    FILE *fp;
    const char *path;
    uint64_t size;
    ckpt_header h;
} ckpt_reader;

static sooc_status rd(ckpt_reader *r, void *buf, size_t n, const char *what) {
    if (n && fread(buf, 1, n, r->fp) != n)
        return sooc_seterr(SOOC_EFORMAT, "%s: truncated checkpoint while reading %s", r->path,
                           what);
    return SOOC_OK;
}

static sooc_status reader_open(ckpt_reader *r, const char *path) {
    memset(r, 0, sizeof *r);
    r->path = path;
    struct stat st;
    if (stat(path, &st) != 0) return sooc_seterr(SOOC_ENOTFOUND, "%s: no such checkpoint", path);
    r->size = (uint64_t)st.st_size;
    r->fp = fopen(path, "rb");
    if (!r->fp) return sooc_seterr(SOOC_EIO, "%s: cannot open checkpoint", path);
    sooc_status s;
    if (r->size < sizeof r->h + 4) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: file too short for a checkpoint (%llu bytes)", path,
                        (unsigned long long)r->size);
        goto fail;
    }
    if ((s = rd(r, &r->h, sizeof r->h, "header"))) goto fail;
    if (memcmp(r->h.magic, CKPT_MAGIC, 8) != 0) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: not a sooc3d nn checkpoint (bad magic)", path);
        goto fail;
    }
    if (r->h.version != SOOC_NN_CKPT_VERSION) {
        s = sooc_seterr(SOOC_EVERSION,
                        "%s: checkpoint version %u, this build reads version %u", path,
                        r->h.version, SOOC_NN_CKPT_VERSION);
        goto fail;
    }
    if (r->h.file_bytes != r->size) {
        s = sooc_seterr(SOOC_EFORMAT,
                        "%s: checkpoint truncated or padded: header says %llu bytes, file has %llu",
                        path, (unsigned long long)r->h.file_bytes, (unsigned long long)r->size);
        goto fail;
    }
    if (r->h.config_bytes > r->size || r->h.trainer_bytes > r->size ||
        r->h.n_total > r->size / 4 || r->h.n_views > r->size / 16) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: checkpoint header sizes exceed the file size", path);
        goto fail;
    }
    /* CRC over everything but the last 4 bytes, with a fixed stack buffer */
    {
        unsigned char buf[16384];
        uint32_t crc = sooc_crc32(0, &r->h, sizeof r->h);
        uint64_t left = r->size - sizeof r->h - 4;
        while (left) {
            size_t k = left > sizeof buf ? sizeof buf : (size_t)left;
            if ((s = rd(r, buf, k, "body"))) goto fail;
            crc = sooc_crc32(crc, buf, k);
            left -= k;
        }
        uint32_t stored;
        if ((s = rd(r, &stored, 4, "CRC"))) goto fail;
        if (stored != crc) {
            s = sooc_seterr(SOOC_EFORMAT, "%s: checkpoint CRC mismatch (corrupt file)", path);
            goto fail;
        }
    }
    if (fseek(r->fp, (long)sizeof r->h, SEEK_SET) != 0) {
        s = sooc_seterr(SOOC_EIO, "%s: seek failed", path);
        goto fail;
    }
    return SOOC_OK;
fail:
    fclose(r->fp);
    r->fp = NULL;
    return s;
}

/* Skip or check the view table. p == NULL: skip. */
static sooc_status reader_table(ckpt_reader *r, const sooc_nn_params *p) {
    sooc_status s;
    if (p && (r->h.n_views != (uint32_t)p->n_views || r->h.n_total != p->n_total))
        return sooc_seterr(SOOC_EINVAL,
                           "%s: checkpoint layout mismatch: file has %u views / %llu floats, "
                           "model has %d views / %zu floats",
                           r->path, r->h.n_views, (unsigned long long)r->h.n_total, p->n_views,
                           p->n_total);
    for (uint32_t i = 0; i < r->h.n_views; i++) {
        uint32_t len, nd;
        char name[64];
        int64_t shape[SOOC_NN_MAX_DIMS];
        uint64_t off;
        if ((s = rd(r, &len, 4, "view name length"))) return s;
        if (len == 0 || len >= sizeof name)
            return sooc_seterr(SOOC_EFORMAT, "%s: view %u: bad name length %u", r->path, i, len);
        if ((s = rd(r, name, len, "view name"))) return s;
        name[len] = 0;
        if ((s = rd(r, &nd, 4, "view ndim"))) return s;
        if (nd < 1 || nd > SOOC_NN_MAX_DIMS)
            return sooc_seterr(SOOC_EFORMAT, "%s: view '%s': bad ndim %u", r->path, name, nd);
        if ((s = rd(r, shape, 8 * (size_t)nd, "view shape"))) return s;
        if ((s = rd(r, &off, 8, "view offset"))) return s;
        if (!p) continue;
        const sooc_nn_param_view *v = &p->views[i];
        int same = strcmp(v->name, name) == 0 && v->ndim == (int)nd && v->offset == off;
        for (uint32_t d = 0; same && d < nd; d++) same = v->shape[d] == shape[d];
        if (!same) {
            char fs[96] = "", ms[96] = "";
            for (uint32_t d = 0; d < nd; d++)
                snprintf(fs + strlen(fs), sizeof fs - strlen(fs), "%s%lld", d ? "x" : "",
                         (long long)shape[d]);
            for (int d = 0; d < v->ndim; d++)
                snprintf(ms + strlen(ms), sizeof ms - strlen(ms), "%s%lld", d ? "x" : "",
                         (long long)v->shape[d]);
            return sooc_seterr(SOOC_EINVAL,
                               "%s: checkpoint layout mismatch at view %u: file has '%s' [%s] at "
                               "offset %llu, model has '%s' [%s] at offset %zu",
                               r->path, i, name, fs, (unsigned long long)off, v->name, ms,
                               v->offset);
        }
    }
    return SOOC_OK;
}

sooc_status sooc_nn_ckpt_read_config(const char *path, size_t max_bytes, void **config,
                                     size_t *config_bytes) {
    *config = NULL;
    *config_bytes = 0;
    ckpt_reader r;
    sooc_status s = reader_open(&r, path);
    if (s) return s;
    if ((s = reader_table(&r, NULL))) goto done;
    if (r.h.config_bytes > max_bytes) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: config blob of %llu bytes exceeds limit %zu", path,
                        (unsigned long long)r.h.config_bytes, max_bytes);
        goto done;
    }
    /* config_bytes <= file size (checked in reader_open) */
    void *buf = sooc_malloc(r.h.config_bytes + 1);
    if (!buf) { s = SOOC_ENOMEM; goto done; }
    if ((s = rd(&r, buf, (size_t)r.h.config_bytes, "config"))) { sooc_free(buf); goto done; }
    ((char *)buf)[r.h.config_bytes] = 0;
    *config = buf;
    *config_bytes = (size_t)r.h.config_bytes;
done:
    fclose(r.fp);
    return s;
}

sooc_status sooc_nn_ckpt_load(const char *path, sooc_nn_params *p, const void *expect_config,
                              size_t expect_config_bytes, void *trainer, size_t trainer_cap,
                              size_t *trainer_bytes) {
    if (!p->w) return sooc_seterr(SOOC_EINVAL, "%s: params not allocated", path);
    if (trainer_bytes) *trainer_bytes = 0;
    ckpt_reader r;
    sooc_status s = reader_open(&r, path);
    if (s) return s;
    int has_opt = (r.h.flags & 1u) != 0;
    size_t slab = p->n_total * sizeof(float);
    if ((s = reader_table(&r, p))) goto done;
    if (r.h.file_bytes != (uint64_t)ftell(r.fp) + r.h.config_bytes + r.h.trainer_bytes +
                              (uint64_t)slab * (has_opt ? 3 : 1) + 4) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: checkpoint section sizes do not add up", path);
        goto done;
    }
    /* config: compare in fixed chunks (no allocation from the file's size) */
    if (expect_config) {
        if (r.h.config_bytes != expect_config_bytes) {
            s = sooc_seterr(SOOC_EINVAL,
                            "%s: model config mismatch (%llu bytes in file, %zu expected)", path,
                            (unsigned long long)r.h.config_bytes, expect_config_bytes);
            goto done;
        }
        unsigned char buf[4096];
        size_t done_b = 0;
        while (done_b < expect_config_bytes) {
            size_t k = expect_config_bytes - done_b;
            if (k > sizeof buf) k = sizeof buf;
            if ((s = rd(&r, buf, k, "config"))) goto done;
            if (memcmp(buf, (const unsigned char *)expect_config + done_b, k) != 0) {
                s = sooc_seterr(SOOC_EINVAL, "%s: model config differs from the expected one",
                                path);
                goto done;
            }
            done_b += k;
        }
    } else if (fseek(r.fp, (long)r.h.config_bytes, SEEK_CUR) != 0) {
        s = sooc_seterr(SOOC_EIO, "%s: seek failed", path);
        goto done;
    }
    if (trainer) {
        if (r.h.trainer_bytes > trainer_cap) {
            s = sooc_seterr(SOOC_EINVAL, "%s: trainer state of %llu bytes exceeds buffer of %zu",
                            path, (unsigned long long)r.h.trainer_bytes, trainer_cap);
            goto done;
        }
        if ((s = rd(&r, trainer, (size_t)r.h.trainer_bytes, "trainer state"))) goto done;
        if (trainer_bytes) *trainer_bytes = (size_t)r.h.trainer_bytes;
    } else if (fseek(r.fp, (long)r.h.trainer_bytes, SEEK_CUR) != 0) {
        s = sooc_seterr(SOOC_EIO, "%s: seek failed", path);
        goto done;
    }
    /* The CRC has already been verified, so reading into p cannot leave it
     * half-updated by a corrupt file (only by an I/O error mid-read). */
    if ((s = rd(&r, p->w, slab, "parameters"))) goto done;
    if (has_opt) {
        if ((s = rd(&r, p->m, slab, "adam m"))) goto done;
        if ((s = rd(&r, p->v, slab, "adam v"))) goto done;
        p->adam_t = r.h.adam_t;
    } else {
        memset(p->m, 0, slab);
        memset(p->v, 0, slab);
        p->adam_t = 0;
    }
done:
    fclose(r.fp);
    return s;
}
