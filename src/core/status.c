/* Status codes, per-thread error messages, log callback. */
#include "sooc3d/core.h"

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *sooc_status_str(sooc_status s) {
    switch (s) {
    case SOOC_OK: return "OK";
    case SOOC_ERR: return "ERR";
    case SOOC_ENOMEM: return "ENOMEM";
    case SOOC_EINVAL: return "EINVAL";
    case SOOC_EIO: return "EIO";
    case SOOC_EFORMAT: return "EFORMAT";
    case SOOC_EVERSION: return "EVERSION";
    case SOOC_ENOTFOUND: return "ENOTFOUND";
    case SOOC_EUNSUPPORTED: return "EUNSUPPORTED";
    case SOOC_ETIMEOUT: return "ETIMEOUT";
    case SOOC_EBUSY: return "EBUSY";
    case SOOC_EEOF: return "EEOF";
    case SOOC_ENUMERIC: return "ENUMERIC";
    case SOOC_EINTERRUPTED: return "EINTERRUPTED";
    }
    return "UNKNOWN";
}

static _Thread_local char g_errmsg[1024];

sooc_status sooc_seterr(sooc_status s, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(g_errmsg, sizeof g_errmsg, fmt, ap);
    va_end(ap);
    return s;
}

sooc_status sooc_adderr(sooc_status s, const char *fmt, ...) {
    char prefix[512], old[sizeof g_errmsg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, g_errmsg, sizeof old);
    size_t np = strlen(prefix), room = sizeof g_errmsg - 1;
    if (np > room) np = room;
    memcpy(g_errmsg, prefix, np);
    size_t pos = np;
    if (pos + 2 <= room) { g_errmsg[pos++] = ':'; g_errmsg[pos++] = ' '; }
    size_t no = strlen(old);
    if (no > room - pos) no = room - pos;
    memcpy(g_errmsg + pos, old, no);
    g_errmsg[pos + no] = 0;
    return s;
}

const char *sooc_errmsg(void) { return g_errmsg; }
void sooc_clearerr(void) { g_errmsg[0] = 0; }

/* ------------------------------------------------------------------- log */

static sooc_log_fn g_log_fn;
static void *g_log_user;
static _Atomic int g_log_level = SOOC_LOG_INFO;

void sooc_log_set_callback(sooc_log_fn fn, void *user) {
    g_log_fn = fn;
    g_log_user = user;
}
void sooc_log_set_level(sooc_log_level l) { atomic_store(&g_log_level, (int)l); }
sooc_log_level sooc_log_get_level(void) { return (sooc_log_level)atomic_load(&g_log_level); }

void sooc_log(sooc_log_level level, const char *fmt, ...) {
    if (!g_log_fn || (int)level < atomic_load(&g_log_level)) return;
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    g_log_fn(g_log_user, level, buf);
}

sooc_status sooc_log_level_parse(const char *s, sooc_log_level *out) {
    static const char *names[] = {"debug", "info", "warn", "error", "fatal"};
    for (int i = 0; i < 5; i++)
        if (s && strcmp(s, names[i]) == 0) { *out = (sooc_log_level)i; return SOOC_OK; }
    return sooc_seterr(SOOC_EINVAL, "log level '%s': expected debug, info, warn or error", s ? s : "(null)");
}

_Noreturn void sooc_assert_fail(const char *expr, const char *file, int line) {
    sooc_log(SOOC_LOG_FATAL, "%s:%d: assertion failed: %s", file, line, expr);
    if (!g_log_fn) fprintf(stderr, "%s:%d: assertion failed: %s\n", file, line, expr);
    abort();
}
