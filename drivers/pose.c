/* Pose sources: TUM trajectory file, live UDP/UNIX datagram stream, pushed
 * buffer. A bounded, time-sorted ring with SLERP interpolation (frame.h). */
#include "sooc3d/frame.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <netdb.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "sooc3d/core.h"
#include "drivers_internal.h"

typedef struct pose_rec {
    int64_t t_ns;
    int kind;       /* sooc_pose_kind of T */
    double T[16];   /* as received: T_wc (camera) or T_base_effector (effector) */
} pose_rec;

struct sooc_pose_src {
    sooc_pose_params p;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    pose_rec *ring;
    int cap, head, n;          /* logical i lives at ring[(head + i) % cap] */
    sooc_pose_stats st;
    /* sequence tracking for the socket stream */
    int have_seq;
    uint32_t last_seq;
    /* socket */
    int fd;
    pthread_t thr;
    int thr_running;
    atomic_int stop;
    char unix_path[sizeof(((struct sockaddr_un *)0)->sun_path)];
};

void sooc_pose_params_default(sooc_pose_params *p) {
    memset(p, 0, sizeof *p);
    p->capacity = 4096;
    sooc_se3_identity(p->T_effector_camera);
    sooc_se3_identity(p->T_world_base);
    p->text_kind = SOOC_POSE_CAMERA;
}

static sooc_status src_new(sooc_pose_src **out, const sooc_pose_params *p) {
    *out = NULL;
    sooc_pose_src *s = sooc_calloc(1, sizeof *s);
    if (!s) return SOOC_ENOMEM;
    if (p) s->p = *p; else sooc_pose_params_default(&s->p);
    if (s->p.capacity <= 1) s->p.capacity = 4096;
    s->cap = s->p.capacity;
    s->ring = sooc_calloc((size_t)s->cap, sizeof *s->ring);
    if (!s->ring) { sooc_free(s); return SOOC_ENOMEM; }
    pthread_mutex_init(&s->mu, NULL);
    pthread_cond_init(&s->cv, NULL);
    s->fd = -1;
    *out = s;
    return SOOC_OK;
}

static pose_rec *at(sooc_pose_src *s, int i) { return &s->ring[(s->head + i) % s->cap]; }

/* First logical index with t >= t_ns (n if none). Caller holds mu. */
static int lower_bound(sooc_pose_src *s, int64_t t_ns) {
    int lo = 0, hi = s->n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (at(s, mid)->t_ns < t_ns) lo = mid + 1; else hi = mid;
    }
    return lo;
}

/* Insert a camera pose. Caller holds mu. Returns 1 if stored. */
static int insert_locked(sooc_pose_src *s, int64_t t_ns, int kind, const double T[16]) {
    int pos = lower_bound(s, t_ns);
    if (pos < s->n && at(s, pos)->t_ns == t_ns) { s->st.duplicates++; return 0; }
    if (s->n == s->cap) {
        if (pos == 0) { s->st.overflow++; return 0; }     /* older than all in a full ring */
        s->head = (s->head + 1) % s->cap;                  /* drop the oldest */
        s->n--;
        pos--;
        s->st.overflow++;
    }
    if (pos < s->n) s->st.out_of_order++;
    for (int i = s->n; i > pos; i--) *at(s, i) = *at(s, i - 1);
    s->n++;
    pose_rec *r = at(s, pos);
    r->t_ns = t_ns;
    r->kind = kind;
    memcpy(r->T, T, sizeof r->T);
    s->st.received++;
    pthread_cond_broadcast(&s->cv);
    return 1;
}

static sooc_status to_camera(sooc_pose_src *s, sooc_pose_kind kind, const double T[16], double Tc[16]) {
    double R[9], t[3], err = 0;
    sooc_se3_to_rt(R, t, T);
    for (int i = 0; i < 16; i++)
        if (!isfinite(T[i])) return sooc_seterr(SOOC_ENUMERIC, "pose: non-finite matrix entry");
    if (!sooc_m3_is_rotation(R, 1e-4, &err))
        return sooc_seterr(SOOC_EINVAL, "pose: rotation part is not a rotation (err %.3g)", err);
    if (kind == SOOC_POSE_CAMERA) { memcpy(Tc, T, 16 * sizeof(double)); return SOOC_OK; }
    if (kind != SOOC_POSE_EFFECTOR) return sooc_seterr(SOOC_EINVAL, "pose: unknown kind %d", (int)kind);
    if (!s->p.has_hand_eye)
        return sooc_seterr(SOOC_EINVAL, "pose: end-effector pose but no hand-eye T_effector_camera given");
    double A[16];
    sooc_se3_mul(A, s->p.T_world_base, T);
    sooc_se3_mul(Tc, A, s->p.T_effector_camera);
    return SOOC_OK;
}

sooc_status sooc_pose_push(sooc_pose_src *s, int64_t t_ns, sooc_pose_kind kind, const double T[16]) {
    double Tc[16];
    sooc_status st = to_camera(s, kind, T, Tc);   /* validates */
    pthread_mutex_lock(&s->mu);
    if (st) s->st.rejected++;
    else insert_locked(s, t_ns, (int)kind, T);
    pthread_mutex_unlock(&s->mu);
    return st;
}

static void tq_to_T(double T[16], const double t[3], const double q[4]) {
    double R[9];
    sooc_quat_to_m3(R, q);
    sooc_se3_from_rt(T, R, t);
}

sooc_status sooc_pose_push_tq(sooc_pose_src *s, int64_t t_ns, sooc_pose_kind kind, const double t[3],
                              const double q[4]) {
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(n > 0.5 && n < 1.5) || !isfinite(t[0] + t[1] + t[2])) {
        pthread_mutex_lock(&s->mu);
        s->st.rejected++;
        pthread_mutex_unlock(&s->mu);
        return sooc_seterr(SOOC_EINVAL, "pose: quaternion norm %.3g is not ~1 or translation not finite", n);
    }
    double T[16];
    tq_to_T(T, t, q);
    return sooc_pose_push(s, t_ns, kind, T);
}

/* Caller holds mu. */
static sooc_status lookup_locked(sooc_pose_src *s, int64_t t_ns, int64_t tol_ns, double out[16], int *need_newer) {
    *need_newer = 0;
    int i = lower_bound(s, t_ns);
    if (i < s->n && at(s, i)->t_ns == t_ns) {
        (void)to_camera(s, (sooc_pose_kind)at(s, i)->kind, at(s, i)->T, out);
        s->st.exact++;
        return SOOC_OK;
    }
    if (i == s->n) {
        *need_newer = 1;
        if (s->n == 0) return sooc_seterr(SOOC_ENOTFOUND, "pose: no poses received yet");
        return sooc_seterr(SOOC_ENOTFOUND, "pose: no pose after t=%lld ns (newest %lld ns)",
                           (long long)t_ns, (long long)at(s, s->n - 1)->t_ns);
    }
    if (i == 0)
        return sooc_seterr(SOOC_ENOTFOUND, "pose: no pose before t=%lld ns (oldest %lld ns)",
                           (long long)t_ns, (long long)at(s, 0)->t_ns);
    const pose_rec *a = at(s, i - 1), *b = at(s, i);
    if (t_ns - a->t_ns > tol_ns || b->t_ns - t_ns > tol_ns)
        return sooc_seterr(SOOC_ENOTFOUND,
                           "pose: gap around t=%lld ns: neighbours %.1f ms before, %.1f ms after (tol %.1f ms)",
                           (long long)t_ns, (double)(t_ns - a->t_ns) * 1e-6, (double)(b->t_ns - t_ns) * 1e-6,
                           (double)tol_ns * 1e-6);
    if (s->p.max_gap_ns > 0 && b->t_ns - a->t_ns > s->p.max_gap_ns)
        return sooc_seterr(SOOC_ENOTFOUND, "pose: gap %.1f ms around t=%lld ns exceeds max_gap",
                           (double)(b->t_ns - a->t_ns) * 1e-6, (long long)t_ns);
    double u = (double)(t_ns - a->t_ns) / (double)(b->t_ns - a->t_ns);
    if (a->kind == b->kind) {
        /* interpolate what was measured (effector poses move smoothly), then
         * apply the hand-eye */
        double Ti[16];
        sooc_se3_interp(Ti, a->T, b->T, u);
        (void)to_camera(s, (sooc_pose_kind)a->kind, Ti, out);
    } else {
        double Ta[16], Tb[16];
        (void)to_camera(s, (sooc_pose_kind)a->kind, a->T, Ta);
        (void)to_camera(s, (sooc_pose_kind)b->kind, b->T, Tb);
        sooc_se3_interp(out, Ta, Tb, u);
    }
    return SOOC_OK;
}

sooc_status sooc_pose_lookup(sooc_pose_src *s, int64_t t_ns, int64_t tol_ns, double T_wc_out[16]) {
    int need;
    pthread_mutex_lock(&s->mu);
    s->st.lookups++;
    sooc_status st = lookup_locked(s, t_ns, tol_ns, T_wc_out, &need);
    if (st) s->st.skipped++; else s->st.hits++;
    pthread_mutex_unlock(&s->mu);
    return st;
}

sooc_status sooc_pose_wait_lookup(sooc_pose_src *s, int64_t t_ns, int64_t tol_ns, int timeout_ms,
                                  double T_wc_out[16]) {
    struct timespec dl;
    clock_gettime(CLOCK_REALTIME, &dl);
    int64_t ns = (int64_t)dl.tv_nsec + (int64_t)(timeout_ms > 0 ? timeout_ms : 0) * 1000000;
    dl.tv_sec += (time_t)(ns / 1000000000);
    dl.tv_nsec = (long)(ns % 1000000000);
    int need;
    pthread_mutex_lock(&s->mu);
    s->st.lookups++;
    sooc_status st;
    for (;;) {
        st = lookup_locked(s, t_ns, tol_ns, T_wc_out, &need);
        if (st == SOOC_OK || !need || timeout_ms <= 0 || atomic_load(&s->stop)) break;
        if (pthread_cond_timedwait(&s->cv, &s->mu, &dl) == ETIMEDOUT) {
            st = lookup_locked(s, t_ns, tol_ns, T_wc_out, &need);
            break;
        }
    }
    if (st) s->st.skipped++; else s->st.hits++;
    pthread_mutex_unlock(&s->mu);
    return st;
}

void sooc_pose_get_stats(sooc_pose_src *s, sooc_pose_stats *out) {
    pthread_mutex_lock(&s->mu);
    *out = s->st;
    out->count = s->n;
    out->t_first_ns = s->n ? at(s, 0)->t_ns : 0;
    out->t_last_ns = s->n ? at(s, s->n - 1)->t_ns : 0;
    pthread_mutex_unlock(&s->mu);
}

sooc_status sooc_pose_open_buffer(sooc_pose_src **out, const sooc_pose_params *p) {
    return src_new(out, p);
}

/* ------------------------------------------------------------ TUM text */

/* Parse whitespace-separated "t tx ty tz qx qy qz qw" (t in seconds) from
 * *pp. Returns 1 on success, 0 on a blank/comment line, -1 on a bad line. */
static int parse_tum_line(const char *line, int64_t *t_ns, double t[3], double q[4]) {
    const char *c = line;
    while (*c == ' ' || *c == '\t' || *c == '\r') c++;
    if (*c == '\0' || *c == '\n' || *c == '#') return 0;
    char *end;
    if (sooc__parse_seconds_ns(c, &end, t_ns)) return -1;
    c = end;
    double v[7];
    for (int k = 0; k < 7; k++) {
        v[k] = strtod(c, &end);
        if (end == c) return -1;
        c = end;
    }
    while (*c == ' ' || *c == '\t' || *c == '\r') c++;
    if (*c != '\0' && *c != '\n' && *c != '#') return -1;
    memcpy(t, v, 3 * sizeof(double));
    memcpy(q, v + 3, 4 * sizeof(double));
    return 1;
}

sooc_status sooc_pose_open_file(sooc_pose_src **out, const char *path, const sooc_pose_params *p) {
    *out = NULL;
    void *buf = NULL;
    size_t n = 0;
    sooc_status st = sooc_file_read_all(path, (size_t)1 << 30, &buf, &n);
    if (st) return sooc_adderr(st, "pose file %s", path);
    /* A file holds all its poses: the ring is as large as its lines (a caller's larger capacity stays) */
    size_t lines = 1;
    for (size_t i = 0; i < n; i++) lines += ((char *)buf)[i] == '\n';
    if (lines > INT_MAX) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EFORMAT, "pose file %s: more than %d lines", path, INT_MAX);
    }
    sooc_pose_params pp;
    if (p) pp = *p;
    else sooc_pose_params_default(&pp), pp.capacity = 2;
    if ((size_t)pp.capacity < lines) pp.capacity = (int)lines;
    sooc_pose_src *s;
    if ((st = src_new(&s, &pp))) { sooc_free(buf); return st; }
    char *cur = buf, *line;
    int lineno = 0;
    while ((line = sooc__next_line(&cur))) {
        lineno++;
        int64_t t_ns;
        double t[3], q[4];
        int r = parse_tum_line(line, &t_ns, t, q);
        if (r < 0) {
            st = sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 't tx ty tz qx qy qz qw'", path, lineno);
            break;
        }
        if (r > 0 && (st = sooc_pose_push_tq(s, t_ns, SOOC_POSE_CAMERA, t, q))) {
            st = sooc_adderr(st, "%s:%d", path, lineno);
            break;
        }
    }
    sooc_free(buf);
    if (st) { sooc_pose_close(s); return st; }
    if (s->n == 0) {
        sooc_pose_close(s);
        return sooc_seterr(SOOC_EFORMAT, "%s: no poses", path);
    }
    *out = s;
    return SOOC_OK;
}

/* ---------------------------------------------------------- wire format */

static void put_u32(uint8_t *b, uint32_t v) { for (int i = 0; i < 4; i++) b[i] = (uint8_t)(v >> (8 * i)); }
static void put_u64(uint8_t *b, uint64_t v) { for (int i = 0; i < 8; i++) b[i] = (uint8_t)(v >> (8 * i)); }
static uint32_t get_u32(const uint8_t *b) {
    uint32_t v = 0;
    for (int i = 0; i < 4; i++) v |= (uint32_t)b[i] << (8 * i);
    return v;
}
static uint64_t get_u64(const uint8_t *b) {
    uint64_t v = 0;
    for (int i = 0; i < 8; i++) v |= (uint64_t)b[i] << (8 * i);
    return v;
}
static void put_f64(uint8_t *b, double d) { uint64_t v; memcpy(&v, &d, 8); put_u64(b, v); }
static double get_f64(const uint8_t *b) { uint64_t v = get_u64(b); double d; memcpy(&d, &v, 8); return d; }

void sooc_pose_packet_encode(uint8_t buf[SOOC_POSE_PACKET_SIZE], const sooc_pose_packet *pk) {
    memset(buf, 0, SOOC_POSE_PACKET_SIZE);
    put_u32(buf, SOOC_POSE_PACKET_MAGIC);
    buf[4] = SOOC_POSE_PACKET_VERSION;
    buf[5] = 0;
    buf[6] = pk->kind == SOOC_POSE_EFFECTOR ? 1 : 0;
    put_u32(buf + 8, pk->seq);
    put_u64(buf + 16, (uint64_t)pk->t_ns);
    for (int i = 0; i < 3; i++) put_f64(buf + 24 + 8 * i, pk->t[i]);
    for (int i = 0; i < 4; i++) put_f64(buf + 48 + 8 * i, pk->q[i]);
    put_u32(buf + 80, sooc_crc32(0, buf, 80));
}

sooc_status sooc_pose_packet_decode(const uint8_t *buf, size_t n, sooc_pose_packet *pk) {
    if (n != SOOC_POSE_PACKET_SIZE)
        return sooc_seterr(SOOC_EFORMAT, "pose packet: %zu bytes, expected %d", n, SOOC_POSE_PACKET_SIZE);
    if (get_u32(buf) != SOOC_POSE_PACKET_MAGIC) return sooc_seterr(SOOC_EFORMAT, "pose packet: bad magic");
    uint32_t crc = sooc_crc32(0, buf, 80);
    if (crc != get_u32(buf + 80))
        return sooc_seterr(SOOC_EFORMAT, "pose packet: CRC mismatch (%08x != %08x)", crc, get_u32(buf + 80));
    unsigned ver = (unsigned)buf[4] | ((unsigned)buf[5] << 8);
    if (ver != SOOC_POSE_PACKET_VERSION)
        return sooc_seterr(SOOC_EVERSION, "pose packet: version %u, this build reads %d", ver,
                           SOOC_POSE_PACKET_VERSION);
    unsigned flags = (unsigned)buf[6] | ((unsigned)buf[7] << 8);
    pk->kind = (flags & 1) ? SOOC_POSE_EFFECTOR : SOOC_POSE_CAMERA;
    pk->seq = get_u32(buf + 8);
    pk->t_ns = (int64_t)get_u64(buf + 16);
    for (int i = 0; i < 3; i++) pk->t[i] = get_f64(buf + 24 + 8 * i);
    for (int i = 0; i < 4; i++) pk->q[i] = get_f64(buf + 48 + 8 * i);
    return SOOC_OK;
}

/* --------------------------------------------------------------- sockets */

typedef struct addr_any {
    struct sockaddr_storage ss;
    socklen_t len;
    int family;
} addr_any;

static sooc_status parse_address(const char *address, addr_any *a, int passive) {
    memset(a, 0, sizeof *a);
    if (!address) return sooc_seterr(SOOC_EINVAL, "pose socket: no address");
    if (strncmp(address, "unix:", 5) == 0) {
        const char *path = address + 5;
        if (strncmp(path, "//", 2) == 0) path += 2;
        struct sockaddr_un *un = (struct sockaddr_un *)&a->ss;
        if (!*path || strlen(path) >= sizeof un->sun_path)
            return sooc_seterr(SOOC_EINVAL, "pose socket %s: bad or too long UNIX path", address);
        un->sun_family = AF_UNIX;
        strcpy(un->sun_path, path);
        a->len = (socklen_t)sizeof *un;
        a->family = AF_UNIX;
        return SOOC_OK;
    }
    if (strncmp(address, "udp:", 4) != 0)
        return sooc_seterr(SOOC_EINVAL, "pose socket %s: expected udp://HOST:PORT or unix:PATH", address);
    char host[256];
    const char *hp = address + 4;
    if (strncmp(hp, "//", 2) == 0) hp += 2;
    const char *colon = strrchr(hp, ':');
    if (!colon || !colon[1])
        return sooc_seterr(SOOC_EINVAL, "pose socket %s: missing :PORT", address);
    size_t hl = (size_t)(colon - hp);
    if (hl >= sizeof host) return sooc_seterr(SOOC_EINVAL, "pose socket %s: host too long", address);
    memcpy(host, hp, hl);
    host[hl] = '\0';
    if (hl >= 2 && host[0] == '[' && host[hl - 1] == ']') {
        memmove(host, host + 1, hl - 2);
        host[hl - 2] = '\0';
    }
    struct addrinfo hints, *res = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_DGRAM;
    hints.ai_flags = passive ? AI_PASSIVE : 0;
    int rc = getaddrinfo(host[0] ? host : NULL, colon + 1, &hints, &res);
    if (rc || !res)
        return sooc_seterr(SOOC_EINVAL, "pose socket %s: %s", address, gai_strerror(rc));
    memcpy(&a->ss, res->ai_addr, res->ai_addrlen);
    a->len = res->ai_addrlen;
    a->family = res->ai_family;
    freeaddrinfo(res);
    return SOOC_OK;
}

static void handle_datagram(sooc_pose_src *s, const uint8_t *buf, size_t n) {
    pthread_mutex_lock(&s->mu);
    s->st.packets++;
    pthread_mutex_unlock(&s->mu);
    if (n == SOOC_POSE_PACKET_SIZE && get_u32(buf) == SOOC_POSE_PACKET_MAGIC) {
        sooc_pose_packet pk;
        if (sooc_pose_packet_decode(buf, n, &pk)) {
            pthread_mutex_lock(&s->mu);
            s->st.bad_packets++;
            pthread_mutex_unlock(&s->mu);
            return;
        }
        int64_t dup0 = 0;
        pthread_mutex_lock(&s->mu);
        dup0 = s->st.duplicates;
        pthread_mutex_unlock(&s->mu);
        if (sooc_pose_push_tq(s, pk.t_ns, pk.kind, pk.t, pk.q)) return;
        pthread_mutex_lock(&s->mu);
        if (s->st.duplicates == dup0) {
            if (!s->have_seq) {
                s->have_seq = 1;
                s->last_seq = pk.seq;
            } else if ((int32_t)(pk.seq - s->last_seq) > 0) {
                s->st.seq_gaps += (int64_t)(pk.seq - s->last_seq) - 1;
                s->last_seq = pk.seq;
            } else if (s->st.seq_gaps > 0) {
                s->st.seq_gaps--;    /* a late packet filled a hole */
            }
        }
        pthread_mutex_unlock(&s->mu);
        return;
    }
    /* Text: one or more lines. A datagram longer than the buffer keeps only
     * its complete lines (a cut line could still parse, with wrong digits). */
    char text[2048];
    size_t m = n < sizeof text - 1 ? n : sizeof text - 1;
    memcpy(text, buf, m);
    text[m] = '\0';
    if (m < n) {
        char *last_nl = strrchr(text, '\n');
        *(last_nl ? last_nl + 1 : text) = '\0';
        pthread_mutex_lock(&s->mu);
        s->st.bad_packets++;
        pthread_mutex_unlock(&s->mu);
    }
    char *cur = text, *line;
    while ((line = sooc__next_line(&cur))) {
        int64_t t_ns;
        double t[3], q[4];
        int r = parse_tum_line(line, &t_ns, t, q);
        if (r < 0) {
            pthread_mutex_lock(&s->mu);
            s->st.bad_packets++;
            pthread_mutex_unlock(&s->mu);
        } else if (r > 0) {
            (void)sooc_pose_push_tq(s, t_ns, s->p.text_kind, t, q);
        }
    }
}

static void *recv_thread(void *arg) {
    sooc_pose_src *s = arg;
    uint8_t buf[4096];
    while (!atomic_load(&s->stop)) {
        struct pollfd pfd = {.fd = s->fd, .events = POLLIN};
        int r = poll(&pfd, 1, 50);
        if (r <= 0) continue;
        for (;;) {
            ssize_t n = recv(s->fd, buf, sizeof buf, MSG_DONTWAIT);
            if (n < 0) break;
            handle_datagram(s, buf, (size_t)n);
        }
    }
    return NULL;
}

sooc_status sooc_pose_open_socket(sooc_pose_src **out, const char *address, const sooc_pose_params *p) {
    *out = NULL;
    addr_any a;
    sooc_status st = parse_address(address, &a, 1);
    if (st) return st;
    sooc_pose_src *s;
    if ((st = src_new(&s, p))) return st;
    s->fd = socket(a.family, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (s->fd < 0) {
        st = sooc_seterr(SOOC_EIO, "pose socket %s: socket: %s", address, strerror(errno));
        goto fail;
    }
    if (s->p.rcvbuf_bytes > 0)
        (void)setsockopt(s->fd, SOL_SOCKET, SO_RCVBUF, &s->p.rcvbuf_bytes, sizeof s->p.rcvbuf_bytes);
    if (a.family == AF_UNIX) {
        struct sockaddr_un *un = (struct sockaddr_un *)&a.ss;
        struct stat sb;
        if (lstat(un->sun_path, &sb) == 0 && S_ISSOCK(sb.st_mode)) unlink(un->sun_path); /* stale */
        snprintf(s->unix_path, sizeof s->unix_path, "%s", un->sun_path);
    } else {
        int one = 1;
        (void)setsockopt(s->fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    }
    if (bind(s->fd, (struct sockaddr *)&a.ss, a.len) < 0) {
        s->unix_path[0] = '\0';
        st = sooc_seterr(SOOC_EIO, "pose socket %s: bind: %s", address, strerror(errno));
        goto fail;
    }
    if (pthread_create(&s->thr, NULL, recv_thread, s)) {
        st = sooc_seterr(SOOC_ERR, "pose socket %s: cannot start the receiver thread", address);
        goto fail;
    }
    s->thr_running = 1;
    *out = s;
    return SOOC_OK;
fail:
    sooc_pose_close(s);
    return st;
}

void sooc_pose_close(sooc_pose_src *s) {
    if (!s) return;
    atomic_store(&s->stop, 1);
    pthread_mutex_lock(&s->mu);
    pthread_cond_broadcast(&s->cv);
    pthread_mutex_unlock(&s->mu);
    if (s->thr_running) pthread_join(s->thr, NULL);
    if (s->fd >= 0) close(s->fd);
    if (s->unix_path[0]) unlink(s->unix_path);
    pthread_mutex_destroy(&s->mu);
    pthread_cond_destroy(&s->cv);
    sooc_free(s->ring);
    sooc_free(s);
}

/* ---------------------------------------------------------------- sender */

struct sooc_pose_sender {
    int fd;
    addr_any a;
};

sooc_status sooc_pose_sender_open(sooc_pose_sender **out, const char *address) {
    *out = NULL;
    sooc_pose_sender *s = sooc_calloc(1, sizeof *s);
    if (!s) return SOOC_ENOMEM;
    sooc_status st = parse_address(address, &s->a, 0);
    if (st) { sooc_free(s); return st; }
    s->fd = socket(s->a.family, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (s->fd < 0) {
        sooc_free(s);
        return sooc_seterr(SOOC_EIO, "pose sender %s: socket: %s", address, strerror(errno));
    }
    *out = s;
    return SOOC_OK;
}

sooc_status sooc_pose_sender_send_raw(sooc_pose_sender *s, const void *data, size_t n) {
    ssize_t r = sendto(s->fd, data, n, 0, (struct sockaddr *)&s->a.ss, s->a.len);
    if (r < 0 || (size_t)r != n) return sooc_seterr(SOOC_EIO, "pose sender: sendto: %s", strerror(errno));
    return SOOC_OK;
}

sooc_status sooc_pose_sender_send(sooc_pose_sender *s, const sooc_pose_packet *pk) {
    uint8_t buf[SOOC_POSE_PACKET_SIZE];
    sooc_pose_packet_encode(buf, pk);
    return sooc_pose_sender_send_raw(s, buf, sizeof buf);
}

void sooc_pose_sender_close(sooc_pose_sender *s) {
    if (!s) return;
    if (s->fd >= 0) close(s->fd);
    sooc_free(s);
}
