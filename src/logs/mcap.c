/* MCAP (major version 0): located from the summary section (chunk indexes
 * and message indexes, the summary CRC checked) when the file has one,
 * otherwise streamed from the start. Chunks are none, lz4 or zstd; their
 * CRCs are checked when they are decompressed. */
#include "logs_impl.h"

#include <stdio.h>

enum {
    OP_HEADER = 0x01, OP_FOOTER = 0x02, OP_SCHEMA = 0x03, OP_CHANNEL = 0x04, OP_MESSAGE = 0x05, OP_CHUNK = 0x06,
    OP_MSGINDEX = 0x07, OP_CHUNKINDEX = 0x08, OP_STATISTICS = 0x0B, OP_DATAEND = 0x0F
};

/* A bounds-checked cursor over a record's content. */
typedef struct mc {
    const uint8_t *p;
    size_t n, i;
    int bad;
} mc;

/* A field of k bytes at c->i; past the end (c->i may have been moved past
 * it by a skip the record declares) it is 0 and the cursor is bad. */
static uint64_t mc_int(mc *c, size_t k) {
    if (c->bad || c->i > c->n || c->n - c->i < k) { c->bad = 1; return 0; }
    const uint8_t *q = c->p + c->i;
    c->i += k;
    return k == 1 ? q[0] : k == 2 ? logs_u16(q) : k == 4 ? logs_u32(q) : logs_u64(q);
}
static const char *mc_str(mc *c, size_t *len) {   /* uint32 length-prefixed */
    size_t n = (size_t)mc_int(c, 4);
    if (c->bad || c->n - c->i < n) { c->bad = 1; *len = 0; return ""; }   /* mc_int left c->i <= c->n */
    const char *s = (const char *)c->p + c->i;
    c->i += n;
    *len = n;
    return s;
}

static sooc_status cut(const sooc_logfile *lf, uint64_t where, const char *what) {
    return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: %s record is cut short (corrupt file)", lf->path,
                       (unsigned long long)where, what);
}

static const sooc_logs_schema *find_schema(const sooc_logfile *lf, int id) {
    for (int i = 0; i < lf->nsc; i++)
        if (lf->sc[i].id == id) return &lf->sc[i];
    return NULL;
}

static sooc_status add_schema(sooc_logfile *lf, const uint8_t *p, size_t n, uint64_t where) {
    mc c = {p, n, 0, 0};
    size_t nn, ne, nd;
    int id = (int)mc_int(&c, 2);
    const char *name = mc_str(&c, &nn), *enc = mc_str(&c, &ne), *data = mc_str(&c, &nd);
    if (c.bad) return cut(lf, where, "schema");
    if (id == 0 || find_schema(lf, id)) return SOOC_OK;
    sooc_status st = sooc_logs_grow((void **)&lf->sc, &lf->capsc, lf->nsc + 1, sizeof *lf->sc, lf->path);
    if (st) return st;
    sooc_logs_schema *s = &lf->sc[lf->nsc];
    s->id = (uint16_t)id;
    s->name = sooc_logs_dupn(name, nn);
    s->encoding = sooc_logs_dupn(enc, ne);
    s->data = sooc_logs_dupn(data, nd);
    if (!s->name || !s->encoding || !s->data) {
        sooc_free(s->name);
        sooc_free(s->encoding);
        sooc_free(s->data);
        return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", lf->path);
    }
    lf->nsc++;
    return SOOC_OK;
}

static sooc_status add_channel(sooc_logfile *lf, const uint8_t *p, size_t n, uint64_t where) {
    mc c = {p, n, 0, 0};
    size_t nt, ne;
    int id = (int)mc_int(&c, 2), sid = (int)mc_int(&c, 2);
    const char *topic = mc_str(&c, &nt), *enc = mc_str(&c, &ne);
    if (c.bad) return cut(lf, where, "channel");
    if (sooc_logs_find_channel(lf, (uint32_t)id) >= 0) return SOOC_OK;
    const sooc_logs_schema *s = find_schema(lf, sid);
    char encs[64];
    snprintf(encs, sizeof encs, "%.*s", (int)(ne < 63 ? ne : 63), enc);
    return sooc_logs_add_channel(lf, (uint32_t)id, topic, nt, s ? s->name : "", s ? strlen(s->name) : 0, encs,
                            s ? s->data : "", s ? strlen(s->data) : 0, sid, NULL);
}

/* The Chunk record at off: its header fields into a sooc_logs_chunk. */
static sooc_status read_chunk_header(sooc_logfile *lf, uint64_t off, sooc_logs_chunk *k) {
    uint8_t h[41];
    sooc_status st = sooc_logs_pread(lf, off, h, sizeof h, "chunk header");
    if (st) return st;
    if (h[0] != OP_CHUNK)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: expected a chunk record, found opcode 0x%02x", lf->path,
                           (unsigned long long)off, h[0]);
    uint64_t len = logs_u64(h + 1);
    uint32_t nc = logs_u32(h + 37);
    if (nc > 64 || len < 40 + (uint64_t)nc) return cut(lf, off, "chunk");
    uint8_t tail[72];
    if ((st = sooc_logs_pread(lf, off + 41, tail, nc + 8, "chunk header"))) return st;
    int comp = sooc_logs_comp_parse((const char *)tail, nc);
    if (comp < 0 || comp == LOGS_COMP_BZ2)
        return sooc_seterr(SOOC_EUNSUPPORTED,
                           "%s: offset %llu: unknown chunk compression '%.*s' (MCAP chunks are read uncompressed, lz4 "
                           "or zstd)", lf->path, (unsigned long long)off, (int)nc, (const char *)tail);
    memset(k, 0, sizeof *k);
    k->pos = off;
    k->usize = logs_u64(h + 25);
    k->crc = logs_u32(h + 33);
    k->comp = comp;
    k->csize = logs_u64(tail + nc);
    k->data_off = off + 41 + nc + 8;
    if (k->csize > len - 40 - nc || k->data_off + k->csize > lf->size)
        return sooc_seterr(SOOC_EFORMAT,
                           "%s: offset %llu: chunk of %llu bytes runs past the end of the file (%llu bytes): the "
                           "file is truncated", lf->path, (unsigned long long)off, (unsigned long long)k->csize,
                           (unsigned long long)lf->size);
    if (k->usize > LOGS_MAX_RECORD)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: chunk of %llu uncompressed bytes is too large", lf->path,
                           (unsigned long long)off, (unsigned long long)k->usize);
    return SOOC_OK;
}

/* Walk the records of a decompressed MCAP chunk (channels, schemas, messages). */
static sooc_status sooc_logs_mcap_scan_chunk(sooc_logfile *lf, int32_t ci, int add_messages) {
    const uint8_t *d;
    size_t n;
    sooc_status st = sooc_logs_chunk_data(lf, ci, &d, &n);
    if (st) return st;
    uint64_t where = lf->chunks[ci].pos;
    size_t i = 0;
    while (i < n) {
        if (n - i < 9) goto bad;
        uint8_t op = d[i];
        uint64_t len = logs_u64(d + i + 1);
        if (len > n - i - 9) goto bad;
        const uint8_t *p = d + i + 9;
        if (op == OP_SCHEMA) st = add_schema(lf, p, (size_t)len, where);
        else if (op == OP_CHANNEL) st = add_channel(lf, p, (size_t)len, where);
        else if (op == OP_MESSAGE && add_messages) {
            if (len < 22) goto bad;
            int ch = sooc_logs_find_channel(lf, logs_u16(p));
            if (ch < 0)
                return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message at chunk byte %zu has unknown channel %u",
                                   lf->path, (unsigned long long)where, i, logs_u16(p));
            st = sooc_logs_add_entry(lf, (int64_t)logs_u64(p + 6), i, ci, ch);
        }
        if (st) return st;
        i += 9 + (size_t)len;
    }
    lf->chunks[ci].scanned = 1;
    return SOOC_OK;
bad:
    return sooc_logs_chunk_cut(lf, where, i, n);
}

/* Message Index records in [off, end) for chunk ci. */
static sooc_status read_msg_indexes(sooc_logfile *lf, int32_t ci, uint64_t off, uint64_t end, uint8_t **buf,
                                    size_t *cap, int *n_index) {
    sooc_status st;
    *n_index = 0;
    /* first pass: are all channels known? (a streamed file may define them inside the chunk) */
    for (int pass = 0; pass < 2; pass++) {
        int unknown = 0;
        for (uint64_t o = off; o < end;) {
            uint8_t h[9];
            if ((st = sooc_logs_pread(lf, o, h, 9, "record header"))) return st;
            uint64_t len = logs_u64(h + 1);
            if (h[0] != OP_MSGINDEX) break;
            if (len > lf->size - o - 9 || len > LOGS_MAX_RECORD) return cut(lf, o, "message index");
            if ((st = sooc_logs_reserve(buf, cap, (size_t)len + 1))) return st;
            if ((st = sooc_logs_pread(lf, o + 9, *buf, (size_t)len, "message index"))) return st;
            mc c = {*buf, (size_t)len, 0, 0};
            uint32_t id = (uint32_t)mc_int(&c, 2);
            uint32_t nb = (uint32_t)mc_int(&c, 4);
            if (c.bad || nb > len - 6 || nb % 16) return cut(lf, o, "message index");
            int ch = sooc_logs_find_channel(lf, id);
            if (ch < 0) unknown = 1;
            if (pass == 1) {
                if (ch < 0)
                    return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message index for unknown channel %u", lf->path,
                                       (unsigned long long)o, id);
                for (uint32_t k = 0; k < nb / 16; k++) {
                    const uint8_t *q = *buf + 6 + 16 * (size_t)k;
                    uint64_t mo = logs_u64(q + 8);
                    if (mo >= lf->chunks[ci].usize)
                        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message index points at byte %llu of a "
                                           "%llu-byte chunk", lf->path, (unsigned long long)o, (unsigned long long)mo,
                                           (unsigned long long)lf->chunks[ci].usize);
                    if ((st = sooc_logs_add_entry(lf, (int64_t)logs_u64(q), mo, ci, ch))) return st;
                }
                (*n_index)++;
            }
            o += 9 + len;
        }
        if (pass == 0 && unknown && (st = sooc_logs_mcap_scan_chunk(lf, ci, 0))) return st;
    }
    return SOOC_OK;
}

/* Streaming read from the start: every record of the data section. */
static sooc_status scan_data(sooc_logfile *lf) {
    uint8_t *buf = NULL;
    size_t cap = 0;
    sooc_status st = SOOC_OK;
    uint64_t off = 8;
    int ended = 0, first = 1;
    while (!st && off < lf->size) {
        uint8_t h[9];
        if ((st = sooc_logs_pread(lf, off, h, 9, "record header"))) break;
        uint64_t len = logs_u64(h + 1);
        if (len > lf->size - off - 9) {
            st = sooc_seterr(SOOC_EFORMAT,
                             "%s: offset %llu: record (opcode 0x%02x) of %llu bytes runs past the end of the file "
                             "(%llu bytes): the file is truncated",
                             lf->path, (unsigned long long)off, h[0], (unsigned long long)len, (unsigned long long)lf->size);
            break;
        }
        if (first && h[0] != OP_HEADER) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: offset 8: the first record is opcode 0x%02x, not a header", lf->path,
                             h[0]);
            break;
        }
        first = 0;
        uint64_t next = off + 9 + len;
        if (h[0] == OP_SCHEMA || h[0] == OP_CHANNEL) {
            if (len > LOGS_MAX_RECORD) { st = cut(lf, off, "schema"); break; }
            if (!(st = sooc_logs_reserve(&buf, &cap, (size_t)len + 1)) && !(st = sooc_logs_pread(lf, off + 9, buf, (size_t)len, "record")))
                st = h[0] == OP_SCHEMA ? add_schema(lf, buf, (size_t)len, off) : add_channel(lf, buf, (size_t)len, off);
        } else if (h[0] == OP_MESSAGE) {
            uint8_t m[22];
            if (len < 22) { st = cut(lf, off, "message"); break; }
            if ((st = sooc_logs_pread(lf, off + 9, m, 22, "message"))) break;
            int ch = sooc_logs_find_channel(lf, logs_u16(m));
            if (ch < 0)
                st = sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message on unknown channel %u", lf->path,
                                 (unsigned long long)off, logs_u16(m));
            else
                st = sooc_logs_add_entry(lf, (int64_t)logs_u64(m + 6), off, -1, ch);
        } else if (h[0] == OP_CHUNK) {
            sooc_logs_chunk k;
            int32_t ci;
            int n_index = 0;
            if ((st = read_chunk_header(lf, off, &k))) break;
            if ((st = sooc_logs_add_chunk(lf, &k, &ci))) break;
            if ((st = read_msg_indexes(lf, ci, next, lf->size, &buf, &cap, &n_index))) break;
            if (n_index == 0) st = sooc_logs_mcap_scan_chunk(lf, ci, 1);
        } else if (h[0] == OP_DATAEND) {
            uint8_t c4[4] = {0};
            if (len >= 4) st = sooc_logs_pread(lf, off + 9, c4, 4, "data end");
            lf->data_end = off;
            lf->data_crc = logs_u32(c4);
            ended = 1;
            break;
        } else if (h[0] == OP_FOOTER) {
            ended = 1;
            break;
        }
        off = next;
    }
    if (!st && !ended)
        st = sooc_seterr(SOOC_EFORMAT, "%s: ends at offset %llu without a Data End or Footer record: the file is "
                         "truncated", lf->path, (unsigned long long)off);
    sooc_free(buf);
    return st;
}

/* Index from the summary section: 1 in *used when it located the messages. */
static sooc_status read_summary(sooc_logfile *lf, int *used) {
    *used = 0;
    uint64_t ss = lf->summary_start, fp = lf->footer_pos;
    if (ss < 8 || ss >= fp)
        return sooc_seterr(SOOC_EFORMAT, "%s: footer puts the summary at offset %llu, outside the file", lf->path,
                           (unsigned long long)ss);
    size_t n = (size_t)(fp + 25 - ss);   /* through the footer's summary_offset_start */
    if (n > LOGS_MAX_RECORD) return sooc_seterr(SOOC_EFORMAT, "%s: summary section too large", lf->path);
    uint8_t *s = sooc_malloc(n), *buf = NULL;
    size_t cap = 0;
    if (!s) return SOOC_ENOMEM;
    sooc_status st = sooc_logs_pread(lf, ss, s, n, "summary section");
    if (!st && lf->summary_crc) {
        uint32_t got = sooc_crc32(0, s, n);
        if (got != lf->summary_crc)
            st = sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: summary CRC mismatch (stored 0x%08x, computed 0x%08x)",
                             lf->path, (unsigned long long)ss, lf->summary_crc, got);
    }
    uint64_t stat_msgs = UINT64_MAX;
    size_t i = 0, m = (size_t)(fp - ss);
    /* schemas and channels first, then the chunk indexes */
    for (int pass = 0; pass < 2 && !st; pass++)
        for (i = 0; i < m && !st;) {
            if (m - i < 9) { st = cut(lf, ss + i, "summary"); break; }
            uint8_t op = s[i];
            uint64_t len = logs_u64(s + i + 1);
            if (len > m - i - 9) { st = cut(lf, ss + i, "summary"); break; }
            const uint8_t *p = s + i + 9;
            uint64_t where = ss + i;
            if (pass == 0 && op == OP_SCHEMA) st = add_schema(lf, p, (size_t)len, where);
            else if (pass == 0 && op == OP_CHANNEL) st = add_channel(lf, p, (size_t)len, where);
            else if (pass == 0 && op == OP_STATISTICS && len >= 8) stat_msgs = logs_u64(p);
            else if (pass == 1 && op == OP_CHUNKINDEX) {
                mc c = {p, (size_t)len, 0, 0};
                c.i = 16;
                uint64_t cstart = mc_int(&c, 8), clen = mc_int(&c, 8);
                uint32_t mapb = (uint32_t)mc_int(&c, 4);
                c.i += mapb;
                uint64_t milen = mc_int(&c, 8);
                if (c.bad || c.i > c.n) { st = cut(lf, where, "chunk index"); break; }
                sooc_logs_chunk k;
                int32_t ci;
                int n_index = 0;
                if ((st = read_chunk_header(lf, cstart, &k))) break;
                if ((st = sooc_logs_add_chunk(lf, &k, &ci))) break;
                if (mapb && milen) {
                    uint64_t a = cstart + clen;
                    if (a > lf->size || milen > lf->size - a) { st = cut(lf, where, "chunk index"); break; }
                    st = read_msg_indexes(lf, ci, a, a + milen, &buf, &cap, &n_index);
                }
                if (!st && n_index == 0) st = sooc_logs_mcap_scan_chunk(lf, ci, 1);
                *used = 1;
            }
            i += 9 + (size_t)len;
        }
    sooc_free(s);
    sooc_free(buf);
    if (!st && *used && stat_msgs != UINT64_MAX && stat_msgs != (uint64_t)lf->ne) {
        /* messages outside chunks: the chunk indexes do not list them */
        *used = 0;
    }
    return st;
}

static void reset_index(sooc_logfile *lf) {
    lf->ne = 0;
    lf->nchunks = 0;
    lf->comp_seen = 0;
    lf->slot[0].chunk = lf->slot[1].chunk = -1;
}

sooc_status sooc_logs_mcap_open(sooc_logfile *lf) {
    if (lf->size < 8 + 9 + 8)
        return sooc_seterr(SOOC_EFORMAT, "%s: %llu bytes is too short for an MCAP file: the file is truncated",
                           lf->path, (unsigned long long)lf->size);
    uint8_t tail[37];
    int has_footer = 0;
    if (lf->size >= 8 + 37) {
        sooc_status st = sooc_logs_pread(lf, lf->size - 37, tail, 37, "footer");
        if (st) return st;
        static const uint8_t magic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
        if (!memcmp(tail + 29, magic, 8) && tail[0] == OP_FOOTER && logs_u64(tail + 1) == 20) {
            has_footer = 1;
            lf->footer_pos = lf->size - 37;
            lf->summary_start = logs_u64(tail + 9);
            lf->summary_crc = logs_u32(tail + 25);
        }
    }
    if (has_footer && lf->summary_start) {
        int used = 0;
        sooc_status st = read_summary(lf, &used);
        if (st) return st;
        if (used) {
            lf->indexed = 1;
            return SOOC_OK;
        }
        reset_index(lf);
    }
    sooc_status st = scan_data(lf);
    if (!st && !has_footer)
        sooc_log(SOOC_LOG_WARN, "%s: no footer (the file ends at byte %llu, after its Data End record): read from the "
                 "data section", lf->path, (unsigned long long)lf->size);
    return st;
}

sooc_status sooc_logs_mcap_message(sooc_logfile *lf, const uint8_t *rec, size_t n, uint64_t where, const uint8_t **data,
                              size_t *size) {
    if (n < 9 || rec[0] != OP_MESSAGE)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: the index points at %s, not a message record", lf->path,
                           (unsigned long long)where, n < 9 ? "the end of the chunk" : "another record");
    uint64_t len = logs_u64(rec + 1);
    if (len < 22 || len > n - 9) return cut(lf, where, "message");
    *data = rec + 9 + 22;
    *size = (size_t)len - 22;
    return SOOC_OK;
}

sooc_status sooc_logs_mcap_verify(sooc_logfile *lf) {
    if (!lf->data_end || !lf->data_crc) {
        /* find the Data End record by walking the data section */
        uint64_t off = 8;
        while (off + 9 <= lf->size) {
            uint8_t h[9];
            sooc_status st = sooc_logs_pread(lf, off, h, 9, "record header");
            if (st) return st;
            uint64_t len = logs_u64(h + 1);
            if (len > lf->size - off - 9) return cut(lf, off, "data section");
            if (h[0] == OP_DATAEND) {
                uint8_t c4[4] = {0};
                if (len >= 4 && (st = sooc_logs_pread(lf, off + 9, c4, 4, "data end"))) return st;
                lf->data_end = off;
                lf->data_crc = logs_u32(c4);
                break;
            }
            if (h[0] == OP_FOOTER) break;
            off += 9 + len;
        }
    }
    if (!lf->data_end || !lf->data_crc) return SOOC_OK;
    uint8_t *buf = sooc_malloc(1 << 20);
    if (!buf) return SOOC_ENOMEM;
    uint32_t crc = 0;
    sooc_status st = SOOC_OK;
    for (uint64_t off = 0; off < lf->data_end && !st;) {
        size_t k = lf->data_end - off < (1u << 20) ? (size_t)(lf->data_end - off) : (1u << 20);
        if (!(st = sooc_logs_pread(lf, off, buf, k, "data section"))) crc = sooc_crc32(crc, buf, k);
        off += k;
    }
    sooc_free(buf);
    if (!st && crc != lf->data_crc)
        st = sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: data section CRC mismatch (stored 0x%08x, computed 0x%08x)",
                         lf->path, (unsigned long long)lf->data_end, lf->data_crc, crc);
    return st;
}
