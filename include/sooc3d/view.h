/*
 * sooc3d live view: a small web server (Debian's libwebsockets) that shows a
 * running node in a browser: the latest colour frame, the map from above with
 * each object's box and id, the object list with presence and sigma, and the
 * node's stats, pushed over a WebSocket at the keyframe rate (docs/logs.md
 * "Live view").
 *
 *   GET /              the page (no external resources)
 *   GET /api/objects   {"epoch": N, "objects": [...]} (the last published table)
 *   GET /api/stats     the last published stats object
 *   GET /frame.jpg     the last published colour frame (JPEG)
 *   WS  /ws            protocol "sooc3d": one text message per publication:
 *                      {"epoch": N, "frame": F, "objects": [...], "stats": {...}}
 *
 * Ownership: sooc_view_start returns a server the caller stops with
 * sooc_view_stop. The publish calls copy what they are given.
 *
 * Threading: the server runs its own thread. sooc_view_publish may be called
 * from any one thread (the node's mapping thread); start and stop from the
 * thread that owns the view.
 *
 * Errors: a port outside 1..65535, a bind address that is not an IPv4
 * address, or a port another program holds is a clear error naming it
 * (SOOC_EINVAL, SOOC_EBUSY); without libwebsockets at build time,
 * SOOC_EUNSUPPORTED. Nothing is printed: libwebsockets' own log goes to the
 * sooc_log callback at debug level.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_VIEW_H
#define SOOC3D_VIEW_H

#include <stdint.h>

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_view sooc_view;

typedef struct sooc_view_params {
    int port;                  /* 1..65535; 0 = any free port (tests; sooc_view_port tells which) */
    const char *bind;          /* IPv4 address to listen on (default "127.0.0.1")               */
} sooc_view_params;

/* One object of the table as the page shows it. */
typedef struct sooc_view_object {
    uint64_t id;
    double x, z, yaw;          /* map frame: floor position (m), yaw about +y (rad)             */
    double size[3];            /* box: x, height, z (m)                                         */
    double presence, sigma_t, sigma_yaw;
    uint32_t obs_count;
} sooc_view_object;

sooc_status sooc_view_start(sooc_view **out, const sooc_view_params *p);
void sooc_view_stop(sooc_view *v);     /* NULL-safe: closes every connection and joins the thread */
int sooc_view_port(const sooc_view *v);
/* 1 when the server was built in (libwebsockets found at build time). */
int sooc_view_available(void);

/* Publish one keyframe's state: the objects (n), the colour frame (RGB8,
 * w x h; NULL keeps the previous one) and a stats JSON object (NULL keeps
 * the previous one). Every WebSocket client gets one message. */
sooc_status sooc_view_publish(sooc_view *v, const sooc_view_object *obj, size_t n, const uint8_t *rgb, int w, int h,
                              const char *stats_json);
/* Publications so far, and WebSocket messages sent (for tests and stats). */
void sooc_view_counts(const sooc_view *v, uint64_t *epoch, uint64_t *ws_sent, int *ws_clients);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_VIEW_H */
