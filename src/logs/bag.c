/* ROS 1 bag format 2.0: the bag header, connection, chunk, index data and
 * chunk info records. Messages are located from the index data records that
 * follow each chunk (no chunk is decompressed for that); a chunk without
 * them, or a bag whose index section was never written (index_pos 0), is
 * walked record by record. */
#include "logs_impl.h"

#include <stdio.h>

enum { OP_MSG = 0x02, OP_BAGHDR = 0x03, OP_INDEX = 0x04, OP_CHUNK = 0x05, OP_CHUNKINFO = 0x06, OP_CONN = 0x07 };

typedef struct bag_str {
    const char *p;
    size_t n;
} bag_str;

typedef struct bag_hdr {
    int op;                    /* -1 when absent */
    uint32_t conn, size, ver, count, conn_count, chunk_count;
    int has_conn, has_time, has_size;
    int64_t time;
    uint64_t index_pos, chunk_pos;
    bag_str compression, topic, type, md5, def;
} bag_hdr;

static int64_t bag_time(const uint8_t *p) { return (int64_t)logs_u32(p) * 1000000000 + (int64_t)logs_u32(p + 4); }

static int name_is(const uint8_t *f, size_t nn, const char *name) {
    return strlen(name) == nn && !memcmp(f, name, nn);
}

/* Parse the "name=value" fields of a record header (or of a connection's data). */
static sooc_status bag_parse(const uint8_t *h, size_t n, bag_hdr *o, const char *path, uint64_t where) {
    memset(o, 0, sizeof *o);
    o->op = -1;
    size_t i = 0;
    while (i < n) {
        if (n - i < 4) goto bad;
        uint32_t fl = logs_u32(h + i);
        i += 4;
        if (fl > n - i) goto bad;
        const uint8_t *f = h + i, *eq = memchr(f, '=', fl);
        i += fl;
        if (!eq) goto bad;
        size_t nn = (size_t)(eq - f), vn = fl - nn - 1;
        const uint8_t *v = eq + 1;
#define FIXED(name, k) (name_is(f, nn, name) && vn == (k))
        if (FIXED("op", 1)) o->op = v[0];
        else if (FIXED("conn", 4)) { o->conn = logs_u32(v); o->has_conn = 1; }
        else if (FIXED("time", 8)) { o->time = bag_time(v); o->has_time = 1; }
        else if (FIXED("index_pos", 8)) o->index_pos = logs_u64(v);
        else if (FIXED("conn_count", 4)) o->conn_count = logs_u32(v);
        else if (FIXED("chunk_count", 4)) o->chunk_count = logs_u32(v);
        else if (FIXED("size", 4)) { o->size = logs_u32(v); o->has_size = 1; }
        else if (FIXED("ver", 4)) o->ver = logs_u32(v);
        else if (FIXED("count", 4)) o->count = logs_u32(v);
        else if (FIXED("chunk_pos", 8)) o->chunk_pos = logs_u64(v);
        else if (name_is(f, nn, "compression")) o->compression = (bag_str){(const char *)v, vn};
        else if (name_is(f, nn, "topic")) o->topic = (bag_str){(const char *)v, vn};
        else if (name_is(f, nn, "type")) o->type = (bag_str){(const char *)v, vn};
        else if (name_is(f, nn, "md5sum")) o->md5 = (bag_str){(const char *)v, vn};
        else if (name_is(f, nn, "message_definition")) o->def = (bag_str){(const char *)v, vn};
        else if (name_is(f, nn, "op") || name_is(f, nn, "conn") || name_is(f, nn, "time") ||
                 name_is(f, nn, "index_pos") || name_is(f, nn, "size") || name_is(f, nn, "chunk_pos"))
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: record field '%.*s' has %zu bytes", path,
                               (unsigned long long)where, (int)nn, (const char *)f, vn);
#undef FIXED
    }
    return SOOC_OK;
bad:
    return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: malformed record header (field at byte %zu of %zu)", path,
                       (unsigned long long)where, i, n);
}

/* A record in the file: its header (parsed into h; its strings live in *buf)
 * and where its data lies. */
typedef struct bag_rec {
    uint64_t off, data_off, next;
    uint32_t data_len;
    bag_hdr h;
} bag_rec;

static sooc_status bag_record_at(sooc_logfile *lf, uint64_t off, uint8_t **buf, size_t *cap, bag_rec *r) {
    uint8_t b4[4];
    sooc_status st = sooc_logs_pread(lf, off, b4, 4, "record header length");
    if (st) return st;
    uint32_t hl = logs_u32(b4);
    if (hl > (1u << 24))
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: record header of %u bytes is implausible (corrupt file)",
                           lf->path, (unsigned long long)off, hl);
    if ((st = sooc_logs_reserve(buf, cap, (size_t)hl + 4))) return st;
    if ((st = sooc_logs_pread(lf, off + 4, *buf, (size_t)hl + 4, "record header"))) return st;
    r->off = off;
    r->data_len = logs_u32(*buf + hl);
    r->data_off = off + 8 + hl;
    r->next = r->data_off + r->data_len;
    if (r->next > lf->size)
        return sooc_seterr(SOOC_EFORMAT,
                           "%s: offset %llu: record of %llu bytes runs past the end of the file (%llu bytes): the "
                           "file is truncated",
                           lf->path, (unsigned long long)off, (unsigned long long)(r->next - off),
                           (unsigned long long)lf->size);
    return bag_parse(*buf, hl, &r->h, lf->path, off);
}

static sooc_status add_connection(sooc_logfile *lf, const bag_hdr *h, const uint8_t *data, size_t n, uint64_t where) {
    if (!h->has_conn)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: connection record without 'conn'", lf->path,
                           (unsigned long long)where);
    if (sooc_logs_find_channel(lf, h->conn) >= 0) return SOOC_OK;
    bag_hdr d;
    sooc_status st = bag_parse(data, n, &d, lf->path, where);
    if (st) return st;
    const bag_str *topic = d.topic.p ? &d.topic : &h->topic;
    if (!topic->p || !d.type.p)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: connection %u has no topic or type", lf->path,
                           (unsigned long long)where, h->conn);
    return sooc_logs_add_channel(lf, h->conn, topic->p, topic->n, d.type.p, d.type.n, "ros1", d.def.p, d.def.n, 0, NULL);
}

/* A connection record of the file (its data is another header). */
static sooc_status read_connection(sooc_logfile *lf, const bag_rec *r) {
    uint8_t *data = sooc_malloc((size_t)r->data_len + 1);
    if (!data) return SOOC_ENOMEM;
    sooc_status st = sooc_logs_pread(lf, r->data_off, data, r->data_len, "connection record");
    if (!st) st = add_connection(lf, &r->h, data, r->data_len, r->off);
    sooc_free(data);
    return st;
}

static sooc_status check_chunk(sooc_logfile *lf, const bag_rec *r, sooc_logs_chunk *c) {
    const bag_hdr *h = &r->h;
    if (h->op != OP_CHUNK)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: expected a chunk record, found op 0x%02x", lf->path,
                           (unsigned long long)r->off, h->op & 0xff);
    int comp = h->compression.p ? sooc_logs_comp_parse(h->compression.p, h->compression.n) : -1;
    if (comp < 0 || comp == LOGS_COMP_ZSTD)
        return sooc_seterr(SOOC_EUNSUPPORTED,
                           "%s: offset %llu: unknown chunk compression '%.*s' (a ROS bag uses none, lz4 or bz2)",
                           lf->path, (unsigned long long)r->off, (int)(h->compression.p ? h->compression.n : 0),
                           h->compression.p ? h->compression.p : "");
    if (!h->has_size)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: chunk without 'size'", lf->path, (unsigned long long)r->off);
    memset(c, 0, sizeof *c);
    c->pos = r->off;
    c->data_off = r->data_off;
    c->csize = r->data_len;
    c->usize = h->size;
    c->comp = comp;
    return SOOC_OK;
}

/* Walk a decompressed chunk: connections, and messages when add_messages. */
static sooc_status scan_chunk(sooc_logfile *lf, int32_t ci, int add_messages) {
    const uint8_t *d;
    size_t n;
    sooc_status st = sooc_logs_chunk_data(lf, ci, &d, &n);
    if (st) return st;
    uint64_t where = lf->chunks[ci].pos;
    size_t i = 0;
    while (i < n) {
        if (n - i < 4) goto bad;
        uint32_t hl = logs_u32(d + i);
        if (hl > n - i - 4 || n - i - 4 - hl < 4) goto bad;
        bag_hdr h;
        if ((st = bag_parse(d + i + 4, hl, &h, lf->path, where))) return st;
        uint32_t dl = logs_u32(d + i + 4 + hl);
        size_t data = i + 8 + hl;
        if (dl > n - data) goto bad;
        if (h.op == OP_CONN) {
            if ((st = add_connection(lf, &h, d + data, dl, where))) return st;
        } else if (h.op == OP_MSG && add_messages) {
            int ch = sooc_logs_find_channel(lf, h.conn);
            if (ch < 0 || !h.has_time)
                return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message at chunk byte %zu %s", lf->path,
                                   (unsigned long long)where, i, ch < 0 ? "has an unknown connection" : "has no time");
            if ((st = sooc_logs_add_entry(lf, h.time, i, ci, ch))) return st;
        }
        i = data + dl;
    }
    lf->chunks[ci].scanned = 1;
    return SOOC_OK;
bad:
    return sooc_logs_chunk_cut(lf, where, i, n);
}

/* The index data records right after a chunk; returns the offset after them. */
static sooc_status read_chunk_index(sooc_logfile *lf, int32_t ci, uint64_t off, uint64_t end, uint8_t **buf,
                                    size_t *cap, uint64_t *after, int *n_index) {
    *n_index = 0;
    sooc_status st;
    while (off < end) {
        bag_rec r;
        if ((st = bag_record_at(lf, off, buf, cap, &r))) return st;
        if (r.h.op != OP_INDEX) break;
        if (r.h.ver != 1)
            return sooc_seterr(SOOC_EVERSION, "%s: offset %llu: index data version %u (only 1 is read)", lf->path,
                               (unsigned long long)off, r.h.ver);
        if ((uint64_t)r.h.count * 12 != r.data_len)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: index data of %u entries holds %u bytes", lf->path,
                               (unsigned long long)off, r.h.count, r.data_len);
        int ch = sooc_logs_find_channel(lf, r.h.conn);
        if (ch < 0)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: index data for unknown connection %u", lf->path,
                               (unsigned long long)off, r.h.conn);
        if ((st = sooc_logs_reserve(buf, cap, r.data_len + 1))) return st;
        if ((st = sooc_logs_pread(lf, r.data_off, *buf, r.data_len, "index data"))) return st;
        for (uint32_t k = 0; k < r.h.count; k++) {
            const uint8_t *p = *buf + 12 * (size_t)k;
            uint32_t o = logs_u32(p + 8);
            if (o >= lf->chunks[ci].usize)
                return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: index entry points at byte %u of a %llu-byte chunk",
                                   lf->path, (unsigned long long)off, o, (unsigned long long)lf->chunks[ci].usize);
            if ((st = sooc_logs_add_entry(lf, bag_time(p), o, ci, ch))) return st;
        }
        (*n_index)++;
        off = r.next;
    }
    *after = off;
    return SOOC_OK;
}

static sooc_status open_chunk(sooc_logfile *lf, const bag_rec *r, uint64_t end, uint8_t **buf, size_t *cap,
                              uint64_t *after) {
    sooc_logs_chunk c;
    int32_t ci;
    int n_index = 0;
    sooc_status st = check_chunk(lf, r, &c);
    if (!st) st = sooc_logs_add_chunk(lf, &c, &ci);
    if (!st) st = read_chunk_index(lf, ci, r->next, end, buf, cap, after, &n_index);
    if (!st && n_index == 0) st = scan_chunk(lf, ci, 1);
    return st;
}

sooc_status sooc_logs_bag_open(sooc_logfile *lf) {
    uint8_t *buf = NULL;
    size_t cap = 0;
    bag_rec r;
    sooc_status st = bag_record_at(lf, 13, &buf, &cap, &r);
    if (st) goto done;
    if (r.h.op != OP_BAGHDR) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: offset 13: expected the bag header record, found op 0x%02x", lf->path,
                         r.h.op & 0xff);
        goto done;
    }
    uint64_t index_pos = r.h.index_pos, first = r.next;
    if (index_pos > lf->size || (index_pos && index_pos < first)) {
        st = sooc_seterr(SOOC_EFORMAT,
                         "%s: the bag header puts the index at offset %llu, %s (%llu bytes): the file is truncated "
                         "(`rosbag reindex` rebuilds the index)",
                         lf->path, (unsigned long long)index_pos,
                         index_pos > lf->size ? "past the end of the file" : "inside the header", (unsigned long long)lf->size);
        goto done;
    }
    if (index_pos) {
        /* index section: connection and chunk info records */
        lf->indexed = 1;
        uint64_t *pos = NULL;
        int64_t npos = 0, cpos = 0;
        for (uint64_t off = index_pos; off < lf->size && !st; off = r.next) {
            if ((st = bag_record_at(lf, off, &buf, &cap, &r))) break;
            if (r.h.op == OP_CONN) {
                st = read_connection(lf, &r);
            } else if (r.h.op == OP_CHUNKINFO) {
                if (r.h.chunk_pos < first || r.h.chunk_pos >= index_pos) {
                    st = sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: chunk info points at offset %llu, outside the data",
                                     lf->path, (unsigned long long)off, (unsigned long long)r.h.chunk_pos);
                    break;
                }
                if ((st = sooc_logs_grow((void **)&pos, &cpos, npos + 1, sizeof *pos, lf->path))) break;
                pos[npos++] = r.h.chunk_pos;
            }
        }
        for (int64_t k = 0; k < npos && !st; k++) {
            uint64_t after;
            if (!(st = bag_record_at(lf, pos[k], &buf, &cap, &r))) st = open_chunk(lf, &r, index_pos, &buf, &cap, &after);
        }
        sooc_free(pos);
    } else {
        /* no index section: walk the records */
        for (uint64_t off = first; off < lf->size && !st;) {
            if ((st = bag_record_at(lf, off, &buf, &cap, &r))) break;
            if (r.h.op == OP_CHUNK) {
                st = open_chunk(lf, &r, lf->size, &buf, &cap, &off);
            } else {
                if (r.h.op == OP_CONN) st = read_connection(lf, &r);
                off = r.next;
            }
        }
    }
done:
    sooc_free(buf);
    return st;
}

sooc_status sooc_logs_bag_message(sooc_logfile *lf, const uint8_t *d, size_t n, uint64_t off, uint64_t where,
                             const uint8_t **data, size_t *size) {
    if (off > n || n - off < 8) goto bad;
    size_t i = (size_t)off;
    uint32_t hl = logs_u32(d + i);
    if (hl > n - i - 4 || n - i - 4 - hl < 4) goto bad;
    bag_hdr h;
    sooc_status st = bag_parse(d + i + 4, hl, &h, lf->path, where);
    if (st) return st;
    uint32_t dl = logs_u32(d + i + 4 + hl);
    if (dl > n - i - 8 - hl) goto bad;
    if (h.op != OP_MSG)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: index points at chunk byte %zu, which holds op 0x%02x, not a "
                                         "message", lf->path, (unsigned long long)where, i, h.op & 0xff);
    *data = d + i + 8 + hl;
    *size = dl;
    return SOOC_OK;
bad:
    return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message record at chunk byte %llu is cut short", lf->path,
                       (unsigned long long)where, (unsigned long long)off);
}
