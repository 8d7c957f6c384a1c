/* A tiny HTTP client for the live view's tests (loopback, plain sockets). */
#ifndef SOOC3D_TEST_VIEW_HTTP_UTIL_H
#define SOOC3D_TEST_VIEW_HTTP_UTIL_H

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static inline char *find(char *h, size_t n, const char *needle, size_t m) {
    for (size_t i = 0; i + m <= n; i++)
        if (!memcmp(h + i, needle, m)) return h + i;
    return NULL;
}

static inline int connect_to(int port) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a)) {
        if (fd >= 0) close(fd);
        return -1;
    }
    return fd;
}

/* Read until `until` appears or the peer closes (2 s at most); returns the bytes read. */
static inline size_t read_some(int fd, char *buf, size_t cap, const char *until, int ms) {
    size_t n = 0;
    while (n + 1 < cap) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, ms) <= 0) break;
        ssize_t r = read(fd, buf + n, cap - 1 - n);
        if (r <= 0) break;
        n += (size_t)r;
        buf[n] = 0;
        if (until && find(buf, n, until, strlen(until))) break;
    }
    buf[n] = 0;
    return n;
}

/* GET path; returns the status code, the body in body (NUL-terminated), its length in *len. */
static inline int http_get(int port, const char *path, char *body, size_t cap, size_t *len) {
    static char buf[1 << 20];
    int fd = connect_to(port);
    if (fd < 0) return -1;
    char req[512];
    int k = snprintf(req, sizeof req, "GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n", path);
    if (write(fd, req, (size_t)k) != k) {
        close(fd);
        return -1;
    }
    size_t n = read_some(fd, buf, sizeof buf, NULL, 2000);
    close(fd);
    int code = 0;
    sscanf(buf, "HTTP/1.%*d %d", &code);
    char *b = find(buf, n, "\r\n\r\n", 4);
    size_t bl = b ? n - (size_t)(b + 4 - buf) : 0;
    if (bl >= cap) bl = cap - 1;
    if (b) memcpy(body, b + 4, bl);
    body[bl] = 0;
    if (len) *len = bl;
    return code;
}

/* The response headers of an upgrade, byte by byte: the first WebSocket frame that may follow stays unread. */
static inline size_t read_headers(int fd, char *buf, size_t cap) {
    size_t n = 0;
    while (n + 1 < cap) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 2000) <= 0 || read(fd, buf + n, 1) != 1) break;
        n++;
        if (n >= 4 && !memcmp(buf + n - 4, "\r\n\r\n", 4)) break;
    }
    buf[n] = 0;
    return n;
}

#endif
