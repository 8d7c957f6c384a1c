/* Clocks and the terminal progress line. */
#include "sooc3d/core.h"

#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

int64_t sooc_now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

int64_t sooc_realtime_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

double sooc_seconds(void) { return (double)sooc_now_ns() * 1e-9; }

static void fmt_hms(char *out, size_t cap, double s) {
    if (s < 0 || s > 1e7) { snprintf(out, cap, "--:--"); return; }
    long t = (long)(s + 0.5);
    if (t >= 3600) snprintf(out, cap, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
    else snprintf(out, cap, "%ld:%02ld", t / 60, t % 60);
}

void sooc_progress_begin(sooc_progress *p, const char *label, uint64_t total) {
    memset(p, 0, sizeof *p);
    p->label = label;
    p->total = total;
    p->t0 = sooc_seconds();
    p->t_last = -1e9;
    p->log_every_s = 10.0;
    p->tty = isatty(2);
}

static void draw(sooc_progress *p, const char *extra, int final) {
    double now = sooc_seconds(), el = now - p->t0;
    double rate = el > 0 ? (double)p->done / el : 0;
    char eta[32], els[32], line[512];
    fmt_hms(eta, sizeof eta, rate > 0 && p->total ? (double)(p->total - p->done) / rate : -1);
    fmt_hms(els, sizeof els, el);
    int pct = p->total ? (int)(100.0 * (double)p->done / (double)p->total) : 0;
    int n = snprintf(line, sizeof line, "%s %llu/%llu %3d%% %.2f it/s %s %s %s", p->label,
                     (unsigned long long)p->done, (unsigned long long)p->total, pct, rate,
                     final ? "took" : "ETA", final ? els : eta, extra ? extra : "");
    if (n < 0) return;
    if (n >= (int)sizeof line) n = (int)sizeof line - 1;
    if (p->tty) {
        int pad = p->last_len > n ? p->last_len - n : 0;
        fprintf(stderr, "\r%s%*s%s", line, pad, "", final ? "\n" : "");
        p->last_len = n;
    } else {
        fprintf(stderr, "%s\n", line);
    }
    fflush(stderr);
    p->t_last = now;
}

void sooc_progress_update(sooc_progress *p, uint64_t done, const char *extra) {
    p->done = done;
    double now = sooc_seconds();
    double gap = p->tty ? 0.1 : p->log_every_s;
    if (now - p->t_last >= gap) draw(p, extra, 0);
}

void sooc_progress_end(sooc_progress *p, const char *extra) {
    p->done = p->total ? p->total : p->done;
    draw(p, extra, 1);
}
