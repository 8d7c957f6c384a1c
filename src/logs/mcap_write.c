/* A minimal MCAP writer: Header, chunks (none, lz4 frames or zstd) holding
 * the Schema, Channel and Message records, a Message Index per channel after
 * each chunk, Data End with the data-section CRC, and a summary (schemas,
 * channels, chunk indexes, statistics, summary offsets, CRC) before the
 * footer. With params.summary = 0 it writes a streamed file: chunks only, no
 * indexes, an empty summary. */
#include "logs_impl.h"

#include <lz4frame.h>
#include <stdio.h>
#include <zstd.h>

typedef struct mw_idx {        /* message index entries of one channel in the open chunk */
    uint64_t *tv;              /* (log_time, offset) pairs */
    size_t n, cap;
} mw_idx;

typedef struct mw_chan {
    uint16_t id, schema;
    char *topic, *encoding;
    uint64_t count;
    mw_idx idx;
} mw_chan;

typedef struct mw_schema {
    uint16_t id;
    char *name, *encoding;
    uint8_t *data;
    size_t n;
} mw_schema;

struct sooc_mcap_writer {
    sooc_afile f;
    sooc_mcap_writer_params p;
    int comp;
    uint64_t pos;              /* bytes written                                      */
    sooc_ros_buf chunk;        /* records of the open chunk                          */
    int64_t chunk_t0, chunk_t1;
    int chunk_has_msg;
    sooc_ros_buf cidx;         /* chunk index records for the summary                */
    sooc_ros_buf tmp;
    mw_chan *ch;
    int nch;
    mw_schema *sc;
    int nsc;
    uint64_t n_msgs, n_chunks;
    int64_t t0, t1;
    uint8_t *cbuf;
    size_t ccap;
    int summing;
    uint32_t sum_crc;
};

static void b_put(sooc_ros_buf *b, const void *d, size_t n) {
    if (b->oom) return;
    if (b->size + n > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->size + n) cap *= 2;
        uint8_t *p = sooc_realloc(b->data, cap);
        if (!p) { b->oom = 1; return; }
        b->data = p;
        b->cap = cap;
    }
    if (n) memcpy(b->data + b->size, d, n);
    b->size += n;
}
static void b_int(sooc_ros_buf *b, uint64_t v, int k) {
    uint8_t q[8];
    for (int i = 0; i < k; i++) q[i] = (uint8_t)(v >> (8 * i));
    b_put(b, q, (size_t)k);
}
static void b_str(sooc_ros_buf *b, const char *s) {
    size_t n = strlen(s);
    b_int(b, n, 4);
    b_put(b, s, n);
}
/* A record: opcode, length, then the content the caller appends; returns where
 * the length goes (patched by rec_end). */
static size_t rec_begin(sooc_ros_buf *b, uint8_t op) {
    b_put(b, &op, 1);
    size_t at = b->size;
    b_int(b, 0, 8);
    return at;
}
static void rec_end(sooc_ros_buf *b, size_t at) {
    if (b->oom) return;
    uint64_t len = b->size - at - 8;
    for (int i = 0; i < 8; i++) b->data[at + i] = (uint8_t)(len >> (8 * i));
}

static sooc_status out(sooc_mcap_writer *w, const void *d, size_t n) {
    if (w->summing) w->sum_crc = sooc_crc32(w->sum_crc, d, n);
    w->pos += n;
    return sooc_afile_write(&w->f, d, n);
}
static sooc_status out_buf(sooc_mcap_writer *w, sooc_ros_buf *b) {
    if (b->oom) return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", w->f.path);
    sooc_status st = out(w, b->data, b->size);
    b->size = 0;
    return st;
}

void sooc_mcap_writer_params_default(sooc_mcap_writer_params *p) {
    memset(p, 0, sizeof *p);
    p->profile = "";
    p->compression = "zstd";
    p->chunk_size = 1 << 20;
    p->summary = 1;
}

static const uint8_t MAGIC[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

sooc_status sooc_mcap_writer_open(sooc_mcap_writer **outp, const char *path, const sooc_mcap_writer_params *pp) {
    *outp = NULL;
    sooc_mcap_writer *w = sooc_calloc(1, sizeof *w);
    if (!w) return SOOC_ENOMEM;
    if (pp) w->p = *pp;
    else sooc_mcap_writer_params_default(&w->p);
    if (!w->p.profile) w->p.profile = "";
    if (!w->p.compression) w->p.compression = "";
    if (!w->p.chunk_size) w->p.chunk_size = 1 << 20;
    w->comp = sooc_logs_comp_parse(w->p.compression, strlen(w->p.compression));
    if (w->comp < 0 || w->comp == LOGS_COMP_BZ2) {
        sooc_free(w);
        return sooc_seterr(SOOC_EINVAL, "%s: MCAP compression '%s' (one of \"\", lz4, zstd)", path, w->p.compression);
    }
    sooc_status st = sooc_afile_open(&w->f, path);
    if (st) {
        sooc_free(w);
        return st;
    }
    sooc_ros_buf *b = &w->tmp;
    b_put(b, MAGIC, 8);
    size_t at = rec_begin(b, 0x01);
    b_str(b, w->p.profile);
    b_str(b, "sooc3d");
    rec_end(b, at);
    if ((st = out_buf(w, b))) {
        sooc_mcap_writer_abort(w);
        return st;
    }
    *outp = w;
    return SOOC_OK;
}

static void schema_record(sooc_ros_buf *b, const mw_schema *s) {
    size_t at = rec_begin(b, 0x03);
    b_int(b, s->id, 2);
    b_str(b, s->name);
    b_str(b, s->encoding);
    b_int(b, s->n, 4);
    b_put(b, s->data, s->n);
    rec_end(b, at);
}
static void channel_record(sooc_ros_buf *b, const mw_chan *c) {
    size_t at = rec_begin(b, 0x04);
    b_int(b, c->id, 2);
    b_int(b, c->schema, 2);
    b_str(b, c->topic);
    b_str(b, c->encoding);
    b_int(b, 0, 4);   /* metadata: empty map */
    rec_end(b, at);
}

sooc_status sooc_mcap_writer_schema(sooc_mcap_writer *w, const char *name, const char *encoding, const void *data,
                                    size_t n, int *id) {
    if (w->nsc >= 65534) return sooc_seterr(SOOC_EINVAL, "%s: too many schemas", w->f.path);
    mw_schema *s = sooc_realloc(w->sc, sizeof *s * (size_t)(w->nsc + 1));
    if (!s) return SOOC_ENOMEM;
    w->sc = s;
    s = &w->sc[w->nsc];
    memset(s, 0, sizeof *s);
    s->id = (uint16_t)(w->nsc + 1);
    s->name = sooc_strdup(name);
    s->encoding = sooc_strdup(encoding);
    s->data = sooc_malloc(n + 1);
    if (!s->name || !s->encoding || !s->data) {
        sooc_free(s->name);
        sooc_free(s->encoding);
        sooc_free(s->data);
        return SOOC_ENOMEM;
    }
    if (n) memcpy(s->data, data, n);
    s->n = n;
    w->nsc++;
    schema_record(&w->chunk, s);
    *id = s->id;
    return SOOC_OK;
}

sooc_status sooc_mcap_writer_channel(sooc_mcap_writer *w, int schema_id, const char *topic,
                                     const char *message_encoding, int *id) {
    if (w->nch >= 65535) return sooc_seterr(SOOC_EINVAL, "%s: too many channels", w->f.path);
    if (schema_id < 0 || schema_id > w->nsc)
        return sooc_seterr(SOOC_EINVAL, "%s: channel %s: no schema %d", w->f.path, topic, schema_id);
    mw_chan *c = sooc_realloc(w->ch, sizeof *c * (size_t)(w->nch + 1));
    if (!c) return SOOC_ENOMEM;
    w->ch = c;
    c = &w->ch[w->nch];
    memset(c, 0, sizeof *c);
    c->id = (uint16_t)w->nch;
    c->schema = (uint16_t)schema_id;
    c->topic = sooc_strdup(topic);
    c->encoding = sooc_strdup(message_encoding);
    if (!c->topic || !c->encoding) {
        sooc_free(c->topic);
        sooc_free(c->encoding);
        return SOOC_ENOMEM;
    }
    w->nch++;
    channel_record(&w->chunk, c);
    *id = c->id;
    return SOOC_OK;
}

static sooc_status flush_chunk(sooc_mcap_writer *w) {
    if (w->chunk.oom) return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", w->f.path);
    if (w->chunk.size == 0) return SOOC_OK;
    const uint8_t *data = w->chunk.data;
    size_t usize = w->chunk.size, csize = usize;
    if (w->comp == LOGS_COMP_ZSTD || w->comp == LOGS_COMP_LZ4) {
        size_t bound = w->comp == LOGS_COMP_ZSTD ? ZSTD_compressBound(usize) : LZ4F_compressFrameBound(usize, NULL);
        sooc_status st = sooc_logs_reserve(&w->cbuf, &w->ccap, bound);
        if (st) return st;
        size_t r = w->comp == LOGS_COMP_ZSTD ? ZSTD_compress(w->cbuf, bound, data, usize, 3)
                                             : LZ4F_compressFrame(w->cbuf, bound, data, usize, NULL);
        if (w->comp == LOGS_COMP_ZSTD ? ZSTD_isError(r) : LZ4F_isError(r))
            return sooc_seterr(SOOC_EIO, "%s: %s compression failed", w->f.path, sooc_logs_comp_name(w->comp));
        data = w->cbuf;
        csize = r;
    }
    uint64_t start = w->pos;
    sooc_ros_buf *b = &w->tmp;
    b->size = 0;
    size_t at = rec_begin(b, 0x06);
    int64_t t0 = w->chunk_has_msg ? w->chunk_t0 : 0, t1 = w->chunk_has_msg ? w->chunk_t1 : 0;
    b_int(b, (uint64_t)t0, 8);
    b_int(b, (uint64_t)t1, 8);
    b_int(b, usize, 8);
    b_int(b, sooc_crc32(0, w->chunk.data, usize), 4);
    b_str(b, w->comp == LOGS_COMP_NONE ? "" : sooc_logs_comp_name(w->comp));
    b_int(b, csize, 8);
    b_put(b, data, csize);
    rec_end(b, at);
    sooc_status st = out_buf(w, b);
    if (st) return st;
    uint64_t chunk_len = w->pos - start, idx_start = w->pos;
    /* message indexes, and the chunk index that points at them */
    sooc_ros_buf map = {0};
    for (int c = 0; c < w->nch && w->p.summary; c++) {
        mw_idx *x = &w->ch[c].idx;
        if (!x->n) continue;
        b_int(&map, w->ch[c].id, 2);
        b_int(&map, w->pos, 8);
        at = rec_begin(b, 0x07);
        b_int(b, w->ch[c].id, 2);
        b_int(b, x->n * 16, 4);
        for (size_t k = 0; k < 2 * x->n; k++) b_int(b, x->tv[k], 8);
        rec_end(b, at);
        if ((st = out_buf(w, b))) break;
    }
    for (int c = 0; c < w->nch; c++) w->ch[c].idx.n = 0;
    if (!st && w->p.summary) {
        sooc_ros_buf *ci = &w->cidx;
        at = rec_begin(ci, 0x08);
        b_int(ci, (uint64_t)t0, 8);
        b_int(ci, (uint64_t)t1, 8);
        b_int(ci, start, 8);
        b_int(ci, chunk_len, 8);
        b_int(ci, map.size, 4);
        b_put(ci, map.data, map.size);
        b_int(ci, w->pos - idx_start, 8);
        b_str(ci, w->comp == LOGS_COMP_NONE ? "" : sooc_logs_comp_name(w->comp));
        b_int(ci, csize, 8);
        b_int(ci, usize, 8);
        rec_end(ci, at);
        if (map.oom || ci->oom) st = sooc_seterr(SOOC_ENOMEM, "%s: out of memory", w->f.path);
    }
    sooc_ros_buf_free(&map);
    w->chunk.size = 0;
    w->chunk_has_msg = 0;
    w->n_chunks++;
    return st;
}

sooc_status sooc_mcap_writer_message(sooc_mcap_writer *w, int channel, int64_t log_time_ns, int64_t publish_time_ns,
                                     const void *data, size_t n) {
    if (channel < 0 || channel >= w->nch) return sooc_seterr(SOOC_EINVAL, "%s: no channel %d", w->f.path, channel);
    mw_chan *c = &w->ch[channel];
    mw_idx *x = &c->idx;
    if (x->n == x->cap) {
        size_t cap = x->cap ? x->cap * 2 : 64;
        uint64_t *p = sooc_realloc(x->tv, cap * 2 * sizeof *p);
        if (!p) return SOOC_ENOMEM;
        x->tv = p;
        x->cap = cap;
    }
    x->tv[2 * x->n] = (uint64_t)log_time_ns;
    x->tv[2 * x->n + 1] = w->chunk.size;
    x->n++;
    sooc_ros_buf *b = &w->chunk;
    size_t at = rec_begin(b, 0x05);
    b_int(b, c->id, 2);
    b_int(b, (uint32_t)c->count, 4);
    b_int(b, (uint64_t)log_time_ns, 8);
    b_int(b, (uint64_t)publish_time_ns, 8);
    b_put(b, data, n);
    rec_end(b, at);
    if (b->oom) return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", w->f.path);
    c->count++;
    if (!w->chunk_has_msg || log_time_ns < w->chunk_t0) w->chunk_t0 = log_time_ns;
    if (!w->chunk_has_msg || log_time_ns > w->chunk_t1) w->chunk_t1 = log_time_ns;
    if (!w->n_msgs || log_time_ns < w->t0) w->t0 = log_time_ns;
    if (!w->n_msgs || log_time_ns > w->t1) w->t1 = log_time_ns;
    w->chunk_has_msg = 1;
    w->n_msgs++;
    return b->size >= w->p.chunk_size ? flush_chunk(w) : SOOC_OK;
}

static void writer_free(sooc_mcap_writer *w) {
    for (int i = 0; i < w->nch; i++) {
        sooc_free(w->ch[i].topic);
        sooc_free(w->ch[i].encoding);
        sooc_free(w->ch[i].idx.tv);
    }
    for (int i = 0; i < w->nsc; i++) {
        sooc_free(w->sc[i].name);
        sooc_free(w->sc[i].encoding);
        sooc_free(w->sc[i].data);
    }
    sooc_free(w->ch);
    sooc_free(w->sc);
    sooc_ros_buf_free(&w->chunk);
    sooc_ros_buf_free(&w->cidx);
    sooc_ros_buf_free(&w->tmp);
    sooc_free(w->cbuf);
    sooc_free(w);
}

void sooc_mcap_writer_abort(sooc_mcap_writer *w) {
    if (!w) return;
    sooc_afile_abort(&w->f);
    writer_free(w);
}

sooc_status sooc_mcap_writer_close(sooc_mcap_writer *w) {
    sooc_status st = flush_chunk(w);
    sooc_ros_buf *b = &w->tmp;
    b->size = 0;
    if (!st) {   /* Data End: CRC of everything written so far */
        size_t at = rec_begin(b, 0x0F);
        b_int(b, w->f.crc, 4);
        rec_end(b, at);
        st = out_buf(w, b);
    }
    uint64_t summary_start = 0, offsets_start = 0;
    if (!st && w->p.summary) {
        summary_start = w->pos;
        w->summing = 1;
        w->sum_crc = 0;
        uint64_t g[4][2];   /* schema, channel, chunk index, statistics: start, length */
        g[0][0] = w->pos;
        for (int i = 0; i < w->nsc; i++) schema_record(b, &w->sc[i]);
        if (!(st = out_buf(w, b))) {
            g[0][1] = w->pos - g[0][0];
            g[1][0] = w->pos;
            for (int i = 0; i < w->nch; i++) channel_record(b, &w->ch[i]);
            st = out_buf(w, b);
        }
        if (!st) {
            g[1][1] = w->pos - g[1][0];
            g[2][0] = w->pos;
            st = out_buf(w, &w->cidx);
        }
        if (!st) {
            g[2][1] = w->pos - g[2][0];
            g[3][0] = w->pos;
            size_t at = rec_begin(b, 0x0B);
            b_int(b, w->n_msgs, 8);
            b_int(b, (uint64_t)w->nsc, 2);
            b_int(b, (uint64_t)w->nch, 4);
            b_int(b, 0, 4);
            b_int(b, 0, 4);
            b_int(b, w->n_chunks, 4);
            b_int(b, (uint64_t)(w->n_msgs ? w->t0 : 0), 8);
            b_int(b, (uint64_t)(w->n_msgs ? w->t1 : 0), 8);
            b_int(b, (uint64_t)w->nch * 10, 4);
            for (int i = 0; i < w->nch; i++) {
                b_int(b, w->ch[i].id, 2);
                b_int(b, w->ch[i].count, 8);
            }
            rec_end(b, at);
            st = out_buf(w, b);
            g[3][1] = w->pos - g[3][0];
        }
        if (!st) {
            offsets_start = w->pos;
            static const uint8_t ops[4] = {0x03, 0x04, 0x08, 0x0B};
            for (int k = 0; k < 4; k++) {
                if (!g[k][1]) continue;
                size_t at = rec_begin(b, 0x0E);
                b_put(b, &ops[k], 1);
                b_int(b, g[k][0], 8);
                b_int(b, g[k][1], 8);
                rec_end(b, at);
            }
            st = out_buf(w, b);
        }
    }
    if (!st) {
        b->size = 0;
        static const uint8_t op = 0x02;
        b_put(b, &op, 1);
        b_int(b, 20, 8);   /* the footer's fixed length: the CRC covers it */
        b_int(b, summary_start, 8);
        b_int(b, offsets_start, 8);
        if (!b->oom && w->summing) w->sum_crc = sooc_crc32(w->sum_crc, b->data, b->size);
        w->summing = 0;
        b_int(b, summary_start ? w->sum_crc : 0, 4);
        b_put(b, MAGIC, 8);
        st = out_buf(w, b);
    }
    if (!st) st = sooc_afile_commit(&w->f);
    else sooc_afile_abort(&w->f);
    writer_free(w);
    return st;
}
