/* The live view's server (include/sooc3d/render.h): libwebsockets in its own
 * thread serving the page, the JSON state, the latest frame as JPEG, and a
 * WebSocket that gets one message per publication. */
#include "sooc3d/render.h"
#include "sooc3d/core.h"

#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

extern const char sooc_view_page[];   /* page.c */

#ifdef SOOC_HAVE_LWS
#include <libwebsockets.h>

/* Is (bind, port) free? Port 0: a free port is chosen and returned. */
static sooc_status probe_port(const char *bind_addr, int *port) {
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)*port);
    if (inet_pton(AF_INET, bind_addr, &a.sin_addr) != 1)
        return sooc_seterr(SOOC_EINVAL, "view.bind: '%s' is not an IPv4 address", bind_addr);
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) return sooc_seterr(SOOC_EIO, "view: socket: %s", strerror(errno));
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sooc_status st = SOOC_OK;
    if (bind(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        int e = errno;
        st = e == EADDRINUSE ? sooc_seterr(SOOC_EBUSY, "view.port %d on %s is in use by another program", *port, bind_addr)
                             : sooc_seterr(SOOC_EIO, "view.port %d on %s: cannot listen there: %s", *port, bind_addr,
                                           strerror(e));
    } else if (*port == 0) {
        socklen_t n = sizeof a;
        if (getsockname(fd, (struct sockaddr *)&a, &n) == 0) *port = ntohs(a.sin_port);
    }
    close(fd);
    return st;
}


struct sooc_view {
    struct lws_context *ctx;
    pthread_t th;
    atomic_int stop;
    int port;
    pthread_mutex_t mu;
    char *objects;             /* "[...]"            */
    char *stats;               /* "{...}"            */
    uint8_t *jpeg;
    size_t njpeg;
    uint64_t epoch, frame, ws_sent;
    int ws_clients;
};

typedef struct http_sess {
    uint8_t *buf;              /* LWS_PRE bytes, then the body */
    size_t len, sent;
} http_sess;

typedef struct ws_sess {
    uint64_t seen;
} ws_sess;

static sooc_view *view_of(struct lws *wsi) { return lws_context_user(lws_get_context(wsi)); }

/* A copy of the body (with LWS_PRE bytes in front) for the session to send. */
static int body(http_sess *s, const void *d, size_t n) {
    s->buf = sooc_malloc(LWS_PRE + n + 1);
    if (!s->buf) return -1;
    memcpy(s->buf + LWS_PRE, d, n);
    s->len = n;
    s->sent = 0;
    return 0;
}

static char *state_json(sooc_view *v, int with_stats);

static int cb_http(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len) {
    http_sess *s = user;
    sooc_view *v;
    switch (reason) {
    case LWS_CALLBACK_HTTP: {
        v = view_of(wsi);
        const char *path = in, *mime = "application/json";
        int ok = 0;
        memset(s, 0, sizeof *s);
        pthread_mutex_lock(&v->mu);
        if (!strcmp(path, "/") || !strcmp(path, "/index.html")) {
            mime = "text/html; charset=utf-8";
            ok = !body(s, sooc_view_page, strlen(sooc_view_page));
        } else if (!strcmp(path, "/api/objects")) {
            char *j = state_json(v, 0);
            ok = j && !body(s, j, strlen(j));
            sooc_free(j);
        } else if (!strcmp(path, "/api/stats")) {
            ok = !body(s, v->stats, strlen(v->stats));
        } else if (!strcmp(path, "/frame.jpg") && v->jpeg) {
            mime = "image/jpeg";
            ok = !body(s, v->jpeg, v->njpeg);
        }
        pthread_mutex_unlock(&v->mu);
        if (!ok) {
            if (lws_return_http_status(wsi, HTTP_STATUS_NOT_FOUND, NULL)) return -1;
            return lws_http_transaction_completed(wsi) ? -1 : 0;
        }
        uint8_t hb[LWS_PRE + 512], *start = hb + LWS_PRE, *p = start, *end = hb + sizeof hb - 1;
        if (lws_add_http_common_headers(wsi, HTTP_STATUS_OK, mime, (lws_filepos_t)s->len, &p, end) ||
            lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_CACHE_CONTROL, (const unsigned char *)"no-store", 8, &p,
                                         end) ||
            lws_finalize_write_http_header(wsi, start, &p, end))
            return 1;
        lws_callback_on_writable(wsi);
        return 0;
    }
    case LWS_CALLBACK_HTTP_WRITEABLE: {
        if (!s->buf) return 0;
        size_t n = s->len - s->sent < 16384 ? s->len - s->sent : 16384;
        int last = s->sent + n == s->len;
        if (lws_write(wsi, s->buf + LWS_PRE + s->sent, n, last ? LWS_WRITE_HTTP_FINAL : LWS_WRITE_HTTP) != (int)n)
            return 1;
        s->sent += n;
        if (!last) {
            lws_callback_on_writable(wsi);
            return 0;
        }
        sooc_free(s->buf);
        s->buf = NULL;
        return lws_http_transaction_completed(wsi) ? -1 : 0;
    }
    case LWS_CALLBACK_CLOSED_HTTP:
        if (s) {
            sooc_free(s->buf);
            s->buf = NULL;
        }
        return 0;
    case LWS_CALLBACK_EVENT_WAIT_CANCELLED:
        lws_callback_on_writable_all_protocol(lws_get_context(wsi), lws_get_protocol(wsi) + 1);
        return 0;
    default:
        return lws_callback_http_dummy(wsi, reason, user, in, len);
    }
}

static int cb_ws(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len) {
    ws_sess *s = user;
    sooc_view *v = view_of(wsi);
    (void)in;
    (void)len;
    switch (reason) {
    case LWS_CALLBACK_ESTABLISHED:
        s->seen = UINT64_MAX;   /* nothing sent yet: the current state goes out first */
        pthread_mutex_lock(&v->mu);
        v->ws_clients++;
        pthread_mutex_unlock(&v->mu);
        lws_callback_on_writable(wsi);
        return 0;
    case LWS_CALLBACK_CLOSED:
        pthread_mutex_lock(&v->mu);
        v->ws_clients--;
        pthread_mutex_unlock(&v->mu);
        return 0;
    case LWS_CALLBACK_SERVER_WRITEABLE: {
        pthread_mutex_lock(&v->mu);
        uint64_t epoch = v->epoch;
        char *j = s->seen == UINT64_MAX || epoch > s->seen ? state_json(v, 1) : NULL;
        pthread_mutex_unlock(&v->mu);
        if (!j) return 0;
        size_t n = strlen(j);
        uint8_t *b = sooc_malloc(LWS_PRE + n);
        int rc = 0;
        if (b) {
            memcpy(b + LWS_PRE, j, n);
            rc = lws_write(wsi, b + LWS_PRE, n, LWS_WRITE_TEXT) < (int)n ? -1 : 0;
            sooc_free(b);
        }
        sooc_free(j);
        if (!rc) {
            s->seen = epoch;
            pthread_mutex_lock(&v->mu);
            v->ws_sent++;
            pthread_mutex_unlock(&v->mu);
        }
        return rc;
    }
    default:
        return 0;
    }
}

static const struct lws_protocols g_protocols[] = {
    {"http", cb_http, sizeof(http_sess), 0, 0, NULL, 0},
    {"sooc3d", cb_ws, sizeof(ws_sess), 65536, 0, NULL, 0},
    {NULL, NULL, 0, 0, 0, NULL, 0}};

/* {"epoch": N, "frame": F, "objects": [...](, "stats": {...})}; the caller holds mu. */
static char *state_json(sooc_view *v, int with_stats) {
    size_t n = strlen(v->objects) + (with_stats ? strlen(v->stats) : 0) + 128;
    char *j = sooc_malloc(n);
    if (!j) return NULL;
    if (with_stats)
        snprintf(j, n, "{\"epoch\": %llu, \"frame\": %llu, \"objects\": %s, \"stats\": %s}", (unsigned long long)v->epoch,
                 (unsigned long long)v->frame, v->objects, v->stats);
    else
        snprintf(j, n, "{\"epoch\": %llu, \"objects\": %s}", (unsigned long long)v->epoch, v->objects);
    return j;
}

static void lws_to_sooc_log(int level, const char *line) {
    (void)level;
    sooc_log(SOOC_LOG_DEBUG, "view: %s", line);
}

static void *service(void *arg) {
    sooc_view *v = arg;
    while (!atomic_load(&v->stop))
        if (lws_service(v->ctx, 0) < 0) break;
    return NULL;
}

int sooc_view_available(void) { return 1; }

sooc_status sooc_view_start(sooc_view **out, const sooc_view_params *p) {
    *out = NULL;
    int port = p ? p->port : 0;
    const char *bind_addr = p && p->bind && *p->bind ? p->bind : "127.0.0.1";
    if (port < 0 || port > 65535) return sooc_seterr(SOOC_EINVAL, "view.port %d: expected 1..65535", port);
    sooc_status st = probe_port(bind_addr, &port);
    if (st) return st;
    sooc_view *v = sooc_calloc(1, sizeof *v);
    if (!v) return SOOC_ENOMEM;
    pthread_mutex_init(&v->mu, NULL);
    v->port = port;
    v->objects = sooc_strdup("[]");
    v->stats = sooc_strdup("{}");
    lws_set_log_level(LLL_ERR | LLL_WARN, lws_to_sooc_log);
    struct lws_context_creation_info info;
    memset(&info, 0, sizeof info);
    info.port = port;
    info.iface = bind_addr;
    info.protocols = g_protocols;
    info.user = v;
    info.options = LWS_SERVER_OPTION_DISABLE_IPV6;
    v->ctx = v->objects && v->stats ? lws_create_context(&info) : NULL;
    if (!v->ctx) {
        st = sooc_seterr(SOOC_EIO, "view: cannot serve on %s:%d (libwebsockets refused; see the debug log)", bind_addr,
                         port);
        goto fail;
    }
    if (pthread_create(&v->th, NULL, service, v)) {
        st = sooc_seterr(SOOC_ERR, "view: cannot start its thread");
        lws_context_destroy(v->ctx);
        goto fail;
    }
    sooc_log(SOOC_LOG_INFO, "view: http://%s:%d/ (the map, the latest frame and the objects, live)", bind_addr, port);
    *out = v;
    return SOOC_OK;
fail:
    sooc_free(v->objects);
    sooc_free(v->stats);
    pthread_mutex_destroy(&v->mu);
    sooc_free(v);
    return st;
}

void sooc_view_stop(sooc_view *v) {
    if (!v) return;
    atomic_store(&v->stop, 1);
    lws_cancel_service(v->ctx);
    pthread_join(v->th, NULL);
    lws_context_destroy(v->ctx);
    sooc_free(v->objects);
    sooc_free(v->stats);
    sooc_free(v->jpeg);
    pthread_mutex_destroy(&v->mu);
    sooc_free(v);
}

int sooc_view_port(const sooc_view *v) { return v ? v->port : 0; }

static double fin(double x) { return isfinite(x) ? x : -1; }

sooc_status sooc_view_publish(sooc_view *v, const sooc_view_object *o, size_t n, const uint8_t *rgb, int w, int h,
                              const char *stats_json) {
    size_t cap = 64 + 320 * n, k = 0;
    char *j = sooc_malloc(cap);
    if (!j) return sooc_seterr(SOOC_ENOMEM, "view: out of memory");
    k += (size_t)snprintf(j + k, cap - k, "[");
    for (size_t i = 0; i < n && k < cap; i++)
        k += (size_t)snprintf(j + k, cap - k,
                              "%s{\"id\": %llu, \"x\": %.4f, \"z\": %.4f, \"yaw\": %.4f, \"size\": [%.3f, %.3f, %.3f], "
                              "\"presence\": %.3f, \"sigma_t\": %.4f, \"sigma_yaw\": %.4f, \"obs\": %u}",
                              i ? ", " : "", (unsigned long long)o[i].id, fin(o[i].x), fin(o[i].z), fin(o[i].yaw),
                              fin(o[i].size[0]), fin(o[i].size[1]), fin(o[i].size[2]), fin(o[i].presence),
                              fin(o[i].sigma_t), fin(o[i].sigma_yaw), o[i].obs_count);
    if (k < cap) snprintf(j + k, cap - k, "]");
    void *jpg = NULL;
    size_t nj = 0;
    if (rgb && w > 0 && h > 0) {
        sooc_image img = {w, h, SOOC_PIX_RGB8, (void *)(uintptr_t)rgb};
        sooc_status st = sooc_jpeg_encode(&img, 80, &jpg, &nj);
        if (st) {
            sooc_free(j);
            return sooc_adderr(st, "view: frame");
        }
    }
    char *stats = stats_json ? sooc_strdup(stats_json) : NULL;
    pthread_mutex_lock(&v->mu);
    sooc_free(v->objects);
    v->objects = j;
    if (stats) {
        sooc_free(v->stats);
        v->stats = stats;
    }
    if (jpg) {
        sooc_free(v->jpeg);
        v->jpeg = jpg;
        v->njpeg = nj;
        v->frame++;
    }
    v->epoch++;
    pthread_mutex_unlock(&v->mu);
    lws_cancel_service(v->ctx);   /* the service thread asks every WebSocket to write */
    return SOOC_OK;
}

void sooc_view_counts(const sooc_view *v, uint64_t *epoch, uint64_t *ws_sent, int *ws_clients) {
    sooc_view *m = (sooc_view *)v;
    pthread_mutex_lock(&m->mu);
    if (epoch) *epoch = m->epoch;
    if (ws_sent) *ws_sent = m->ws_sent;
    if (ws_clients) *ws_clients = m->ws_clients;
    pthread_mutex_unlock(&m->mu);
}

#else /* no libwebsockets */

int sooc_view_available(void) { return 0; }
sooc_status sooc_view_start(sooc_view **out, const sooc_view_params *p) {
    (void)p;
    *out = NULL;
    return sooc_seterr(SOOC_EUNSUPPORTED, "view: built without libwebsockets (libwebsockets-dev)");
}
void sooc_view_stop(sooc_view *v) { (void)v; }
int sooc_view_port(const sooc_view *v) { (void)v; return 0; }
sooc_status sooc_view_publish(sooc_view *v, const sooc_view_object *o, size_t n, const uint8_t *rgb, int w, int h,
                              const char *stats_json) {
    (void)v, (void)o, (void)n, (void)rgb, (void)w, (void)h, (void)stats_json;
    return SOOC_EUNSUPPORTED;
}
void sooc_view_counts(const sooc_view *v, uint64_t *epoch, uint64_t *ws_sent, int *ws_clients) {
    (void)v;
    if (epoch) *epoch = 0;
    if (ws_sent) *ws_sent = 0;
    if (ws_clients) *ws_clients = 0;
}
#endif
