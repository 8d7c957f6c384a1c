/* The log reader both formats share: open by magic, the channel table, the
 * time-ordered message index, chunk decompression (LZ4 frames, bz2, zstd)
 * with a two-chunk cache, and random access to messages. */
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

static const uint8_t BAG_MAGIC[13] = "#ROSBAG V2.0\n";
static const uint8_t MCAP_MAGIC[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

sooc_logfile_kind sooc_logfile_detect(const char *path) {
    struct stat sb;
    if (!path || stat(path, &sb) != 0 || !S_ISREG(sb.st_mode)) return SOOC_LOGFILE_NONE;
    FILE *fp = fopen(path, "rb");
    if (!fp) return SOOC_LOGFILE_NONE;
    uint8_t b[13] = {0};
    size_t n = fread(b, 1, sizeof b, fp);
    fclose(fp);
    if (n >= 8 && !memcmp(b, MCAP_MAGIC, 8)) return SOOC_LOGFILE_MCAP;
    if (n >= 9 && !memcmp(b, "#ROSBAG V", 9)) return SOOC_LOGFILE_ROSBAG;
    return SOOC_LOGFILE_NONE;
}

const char *sooc_logfile_kind_name(sooc_logfile_kind k) {
    return k == SOOC_LOGFILE_ROSBAG ? "rosbag" : k == SOOC_LOGFILE_MCAP ? "mcap" : "none";
}

/* ------------------------------------------------------------ open/close */

static int cmp_entry(const void *a, const void *b) {
    const sooc_logs_entry *x = a, *y = b;
    if (x->t != y->t) return x->t < y->t ? -1 : 1;
    if (x->chunk != y->chunk) return x->chunk < y->chunk ? -1 : 1;
    if (x->off != y->off) return x->off < y->off ? -1 : 1;
    return 0;
}

static sooc_status finish_index(sooc_logfile *lf) {
    if (lf->ne > 1) qsort(lf->e, (size_t)lf->ne, sizeof *lf->e, cmp_entry);
    for (int i = 0; i < lf->nch; i++) lf->ch[i].pub.count = 0;
    for (int64_t k = 0; k < lf->ne; k++) {
        int c = lf->e[k].ch;
        if (c < 0 || c >= lf->nch)
            return sooc_seterr(SOOC_EFORMAT, "%s: a message refers to an unknown channel", lf->path);
        lf->ch[c].pub.count++;
    }
    for (int i = 0; i < lf->nch; i++) {
        sooc_logs_chan *c = &lf->ch[i];
        c->msgs = c->pub.count ? sooc_malloc(sizeof(int64_t) * (size_t)c->pub.count) : NULL;
        if (c->pub.count && !c->msgs) return sooc_seterr(SOOC_ENOMEM, "%s: out of memory", lf->path);
        c->nmsgs = 0;
    }
    for (int64_t k = 0; k < lf->ne; k++) {
        sooc_logs_chan *c = &lf->ch[lf->e[k].ch];
        if (c->nmsgs == 0) c->pub.t_first_ns = lf->e[k].t;
        c->pub.t_last_ns = lf->e[k].t;
        c->msgs[c->nmsgs++] = k;
    }
    for (int i = 0; i < lf->nch; i++) {
        sooc_logs_chan *c = &lf->ch[i];
        c->pub.topic = c->topic;
        c->pub.type = c->type;
        c->pub.encoding = c->encoding;
        c->pub.enc = sooc_msg_encoding_parse(c->encoding);
        c->pub.definition = c->definition;
    }
    return SOOC_OK;
}

sooc_status sooc_logfile_open(sooc_logfile **out, const char *path) {
    *out = NULL;
    sooc_logfile *lf = sooc_calloc(1, sizeof *lf);
    if (!lf) return SOOC_ENOMEM;
    lf->fd = -1;
    lf->slot[0].chunk = lf->slot[1].chunk = -1;
    lf->path = sooc_strdup(path ? path : "");
    sooc_status st = SOOC_OK;
    if (!lf->path) { st = SOOC_ENOMEM; goto fail; }
    lf->fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat sb;
    if (lf->fd < 0) {
        st = sooc_seterr(errno == ENOENT ? SOOC_ENOTFOUND : SOOC_EIO, "%s: cannot open: %s", path, strerror(errno));
        goto fail;
    }
    if (fstat(lf->fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        st = sooc_seterr(SOOC_EINVAL, "%s: not a regular file", path);
        goto fail;
    }
    lf->size = (uint64_t)sb.st_size;
    if (lf->size == 0) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: empty file (0 bytes): not a ROS bag or MCAP file", path);
        goto fail;
    }
    uint8_t head[13] = {0};
    size_t nh = lf->size < sizeof head ? (size_t)lf->size : sizeof head;
    if ((st = sooc_logs_pread(lf, 0, head, nh, "magic"))) goto fail;
    if (nh >= 8 && !memcmp(head, MCAP_MAGIC, 8)) {
        lf->kind = SOOC_LOGFILE_MCAP;
        st = sooc_logs_mcap_open(lf);
    } else if (nh == 13 && !memcmp(head, BAG_MAGIC, 13)) {
        lf->kind = SOOC_LOGFILE_ROSBAG;
        st = sooc_logs_bag_open(lf);
    } else if (nh >= 9 && !memcmp(head, "#ROSBAG V", 9)) {
        st = sooc_seterr(SOOC_EVERSION, "%s: ROS bag version '%.3s' is not read (only 2.0; `rosbag fix` migrates "
                                        "older bags)", path, (const char *)head + 9);
    } else if (nh >= 5 && !memcmp(head, MCAP_MAGIC, 5)) {
        st = sooc_seterr(SOOC_EVERSION, "%s: MCAP major version '%c' is not read (only '0')", path, head[5]);
    } else {
        st = sooc_seterr(SOOC_EFORMAT, "%s: not a ROS bag (#ROSBAG V2.0) or MCAP file (bad magic at offset 0)", path);
    }
    if (st) goto fail;
    if ((st = finish_index(lf))) goto fail;
    *out = lf;
    return SOOC_OK;
fail:
    sooc_logfile_close(lf);
    return st;
}

void sooc_logfile_close(sooc_logfile *lf) {
    if (!lf) return;
    if (lf->fd >= 0) close(lf->fd);
    for (int i = 0; i < lf->nch; i++) {
        sooc_free(lf->ch[i].topic);
        sooc_free(lf->ch[i].type);
        sooc_free(lf->ch[i].encoding);
        sooc_free(lf->ch[i].definition);
        sooc_free(lf->ch[i].msgs);
    }
    for (int i = 0; i < lf->nsc; i++) {
        sooc_free(lf->sc[i].name);
        sooc_free(lf->sc[i].encoding);
        sooc_free(lf->sc[i].data);
    }
    sooc_free(lf->sc);
    sooc_free(lf->ch);
    sooc_free(lf->chunks);
    sooc_free(lf->e);
    sooc_free(lf->slot[0].buf);
    sooc_free(lf->slot[1].buf);
    sooc_free(lf->raw);
    sooc_free(lf->path);
    sooc_free(lf);
}

/* ------------------------------------------------------------- queries */

const char *sooc_logfile_path(const sooc_logfile *lf) { return lf->path; }

void sooc_logfile_get_info(const sooc_logfile *lf, sooc_logfile_info *o) {
    memset(o, 0, sizeof *o);
    o->kind = lf->kind;
    o->file_size = (int64_t)lf->size;
    o->n_messages = lf->ne;
    o->n_chunks = lf->nchunks;
    o->n_channels = lf->nch;
    o->indexed = lf->indexed;
    if (lf->ne) {
        o->t_first_ns = lf->e[0].t;
        o->t_last_ns = lf->e[lf->ne - 1].t;
    }
    size_t m = 0;
    for (int c = 0; c < 4; c++)
        if (lf->comp_seen & (1u << c)) {
            int k = snprintf(o->compression + m, sizeof o->compression - m, "%s%s", m ? "+" : "", sooc_logs_comp_name(c));
            if (k > 0 && (size_t)k < sizeof o->compression - m) m += (size_t)k;
        }
    if (!m) snprintf(o->compression, sizeof o->compression, "none");
}

int sooc_logfile_channel_count(const sooc_logfile *lf) { return lf->nch; }

const sooc_logfile_channel *sooc_logfile_channel_get(const sooc_logfile *lf, int i) {
    return i >= 0 && i < lf->nch ? &lf->ch[i].pub : NULL;
}

int sooc_logfile_find(const sooc_logfile *lf, const char *topic) {
    for (int i = 0; topic && i < lf->nch; i++)
        if (!strcmp(lf->ch[i].topic, topic)) return i;
    return -1;
}

const int64_t *sooc_logfile_channel_msgs(const sooc_logfile *lf, int ch, int64_t *n) {
    if (ch < 0 || ch >= lf->nch) {
        *n = 0;
        return NULL;
    }
    *n = lf->ch[ch].nmsgs;
    return lf->ch[ch].msgs;
}

int64_t sooc_logfile_count(const sooc_logfile *lf) { return lf->ne; }

sooc_status sooc_logfile_entry(const sooc_logfile *lf, int64_t k, int *channel, int64_t *t_ns) {
    if (k < 0 || k >= lf->ne)
        return sooc_seterr(SOOC_EINVAL, "%s: message %lld out of range (0..%lld)", lf->path, (long long)k,
                           (long long)lf->ne - 1);
    if (channel) *channel = lf->e[k].ch;
    if (t_ns) *t_ns = lf->e[k].t;
    return SOOC_OK;
}

sooc_status sooc_logfile_read(sooc_logfile *lf, int64_t k, sooc_logfile_msg *m) {
    sooc_status st = sooc_logfile_entry(lf, k, NULL, NULL);
    if (st) return st;
    const sooc_logs_entry *e = &lf->e[k];
    memset(m, 0, sizeof *m);
    m->channel = e->ch;
    m->t_ns = e->t;
    if (e->chunk >= 0) {
        const uint8_t *buf;
        size_t n;
        m->offset = lf->chunks[e->chunk].pos;
        if ((st = sooc_logs_chunk_data(lf, e->chunk, &buf, &n))) return st;
        if (lf->kind == SOOC_LOGFILE_ROSBAG)
            st = sooc_logs_bag_message(lf, buf, n, e->off, m->offset, &m->data, &m->size);
        else if (e->off > n)
            st = sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: message index points past its chunk", lf->path,
                             (unsigned long long)m->offset);
        else
            st = sooc_logs_mcap_message(lf, buf + e->off, n - (size_t)e->off, m->offset, &m->data, &m->size);
    } else {
        /* an unchunked MCAP message record at file offset e->off */
        uint8_t h[9];
        m->offset = e->off;
        if ((st = sooc_logs_pread(lf, e->off, h, 9, "record header"))) return st;
        uint64_t len = logs_u64(h + 1);
        if (len > LOGS_MAX_RECORD)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %llu: record of %llu bytes is too large", lf->path,
                               (unsigned long long)e->off, (unsigned long long)len);
        if ((st = sooc_logs_reserve(&lf->raw, &lf->rawcap, (size_t)len + 9))) return st;
        memcpy(lf->raw, h, 9);
        if ((st = sooc_logs_pread(lf, e->off + 9, lf->raw + 9, (size_t)len, "message record"))) return st;
        st = sooc_logs_mcap_message(lf, lf->raw, (size_t)len + 9, e->off, &m->data, &m->size);
    }
    return st;
}

sooc_status sooc_logfile_verify(sooc_logfile *lf) {
    for (int64_t c = 0; c < lf->nchunks; c++) {
        const uint8_t *d;
        size_t n;
        sooc_status st = sooc_logs_chunk_data(lf, (int32_t)c, &d, &n);
        if (st) return st;
    }
    return lf->kind == SOOC_LOGFILE_MCAP ? sooc_logs_mcap_verify(lf) : SOOC_OK;
}
