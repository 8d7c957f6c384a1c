/* The live view's server on a free loopback port: the page, /api/objects,
 * /frame.jpg and 404s over plain HTTP; a WebSocket client (raw socket,
 * RFC 6455 handshake) gets one message per publication; a port in use, a
 * bad port and a bad address are clear errors; and Debian's chromium in
 * headless mode loads the page and its screenshot shows the objects' boxes
 * (skipped with a message when chromium is not installed). */
#include "check.h"
#include "http_util.h"
#include "sooc3d/core.h"
#include "sooc3d/render.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

/* One unmasked server text frame from fd into out; payload length or -1. */
static long ws_frame(int fd, char *out, size_t cap) {
    unsigned char h[10];
    char tmp[16];
    if (read_some(fd, tmp, 3, NULL, 2000) < 2) return -1;
    memcpy(h, tmp, 2);
    if ((h[0] & 0x0f) != 1) return -1;
    size_t len = h[1] & 0x7f;
    if (len == 126) {
        if (read(fd, h + 2, 2) != 2) return -1;
        len = ((size_t)h[2] << 8) | h[3];
    } else if (len == 127) {
        return -1;
    }
    if (len + 1 > cap) return -1;
    size_t got = 0;
    while (got < len) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 2000) <= 0) return -1;
        ssize_t r = read(fd, out + got, len - got);
        if (r <= 0) return -1;
        got += (size_t)r;
    }
    out[len] = 0;
    return (long)len;
}

static const sooc_view_object g_obj[3] = {
    {1, 0.0, 0.0, 0.0, {0.4, 0.3, 0.4}, 1.0, 0.02, 0.1, 3},
    {2, 1.0, 0.5, 0.7, {0.6, 0.2, 0.3}, 1.0, 0.03, 0.2, 2},
    {3, -0.8, 1.2, -0.3, {0.3, 0.5, 0.3}, 1.0, 0.01, 0.1, 5},
};

/* Pixels of the screenshot within 12 levels of #rrggbb. */
static int count_colour(const sooc_image *img, uint32_t rgb) {
    int n = 0;
    const uint8_t *p = img->data;
    for (int i = 0; i < img->width * img->height; i++) {
        int dr = p[3 * i] - (int)(rgb >> 16), dg = p[3 * i + 1] - (int)((rgb >> 8) & 255), db = p[3 * i + 2] - (int)(rgb & 255);
        n += abs(dr) < 12 && abs(dg) < 12 && abs(db) < 12;
    }
    return n;
}

static void browser(int port) {
    if (system("command -v chromium > /dev/null 2>&1") != 0) {
        printf("  chromium: SKIP: Debian's chromium is not installed\n");
        return;
    }
    char shot[256], cmd[1024];
    snprintf(shot, sizeof shot, "/tmp/sooc_view_%d.png", (int)getpid());
    snprintf(cmd, sizeof cmd,
             "timeout 90 chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --no-first-run "
             "--user-data-dir=/tmp/sooc_view_chromium_%d --window-size=1200,560 --virtual-time-budget=5000 "
             "--screenshot=%s http://127.0.0.1:%d/ > /dev/null 2>&1",
             (int)getpid(), shot, port);
    int rc = system(cmd);
    sooc_image img = {0};
    CHECK_MSG(rc == 0 && sooc_png_read(shot, &img) == SOOC_OK, "chromium screenshot failed (%d)", rc);
    if (img.data) {
        /* PALETTE[id % 8] of the page: ids 1, 2, 3 */
        int c1 = count_colour(&img, 0x3cb44b), c2 = count_colour(&img, 0xffe119), c3 = count_colour(&img, 0x4363d8);
        CHECK_MSG(c1 > 200 && c2 > 200 && c3 > 200, "screenshot: %d, %d, %d pixels of the three boxes' colours", c1, c2, c3);
        printf("  chromium headless: the screenshot shows the 3 boxes (%d, %d, %d pixels)\n", c1, c2, c3);
    }
    sooc_image_free(&img);
    if (!getenv("SOOC_VIEW_KEEP")) remove(shot);
    snprintf(cmd, sizeof cmd, "rm -rf /tmp/sooc_view_chromium_%d", (int)getpid());
    if (system(cmd) != 0) printf("could not remove the chromium profile\n");
}

int main(void) {
    if (!sooc_view_available()) {
        printf("test_view: SKIP: built without libwebsockets (libwebsockets-dev)\n");
        return SOOC_TEST_SKIP;
    }
    sooc_view *v = NULL;
    sooc_view_params p = {0, "127.0.0.1"};
    CHECK_OK(sooc_view_start(&v, &p));
    if (!v) return check_report("test_view");
    int port = sooc_view_port(v);
    static char body[1 << 20];
    size_t len;
    CHECK(http_get(port, "/", body, sizeof body, &len) == 200 && strstr(body, "<canvas") && strstr(body, "WebSocket"));
    CHECK(http_get(port, "/api/objects", body, sizeof body, &len) == 200 && strstr(body, "\"objects\": []"));
    CHECK(http_get(port, "/frame.jpg", body, sizeof body, &len) == 404);
    CHECK(http_get(port, "/nope", body, sizeof body, &len) == 404);

    /* a WebSocket client: the current state at once, then one message per publication */
    int ws = connect_to(port);
    CHECK(ws >= 0);
    const char *hs = "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                     "Sec-WebSocket-Protocol: sooc3d\r\n\r\n";
    CHECK(write(ws, hs, strlen(hs)) == (ssize_t)strlen(hs));
    char resp[2048];
    read_headers(ws, resp, sizeof resp);
    CHECK_MSG(strstr(resp, "101") && strstr(resp, "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="), "handshake: %s", resp);
    static char msg[1 << 16];
    CHECK(ws_frame(ws, msg, sizeof msg) > 0 && strstr(msg, "\"epoch\": 0"));
    static uint8_t rgb[64 * 48 * 3];
    for (size_t i = 0; i < sizeof rgb; i++) rgb[i] = (uint8_t)(i * 7);
    for (int e = 1; e <= 3; e++) {
        CHECK_OK(sooc_view_publish(v, g_obj, (size_t)e, rgb, 64, 48, "{\"keyframes\": 1}"));
        long n = ws_frame(ws, msg, sizeof msg);
        char want[64];
        snprintf(want, sizeof want, "\"epoch\": %d", e);
        CHECK_MSG(n > 0 && strstr(msg, want) && strstr(msg, "\"keyframes\": 1"), "message %d: %s", e, msg);
        int ids = 0;
        for (const char *q = msg; (q = strstr(q, "\"id\": ")); q++) ids++;
        CHECK_MSG(ids == e, "message %d holds %d objects", e, ids);
    }
    uint64_t epoch, sent;
    int clients;
    /* the server counts a message after lws_write returns, which can be after the client has read it */
    for (int t = 0; t < 200; t++) {
        sooc_view_counts(v, &epoch, &sent, &clients);
        if (sent >= 4) break;
        usleep(10000);
    }
    CHECK_MSG(epoch == 3 && sent == 4 && clients == 1, "epoch %llu sent %llu clients %d", (unsigned long long)epoch,
              (unsigned long long)sent, clients);
    CHECK(http_get(port, "/api/objects", body, sizeof body, &len) == 200 && strstr(body, "\"epoch\": 3") &&
          strstr(body, "\"id\": 3"));
    CHECK(http_get(port, "/frame.jpg", body, sizeof body, &len) == 200 && len > 100 && (unsigned char)body[0] == 0xFF &&
          (unsigned char)body[1] == 0xD8);
    printf("  HTTP: /, /api/objects, /frame.jpg (%zu bytes), 404; WebSocket: %llu messages for 3 publications + the "
           "first state\n", len, (unsigned long long)sent);
    close(ws);

    /* errors */
    sooc_view *w = NULL;
    sooc_view_params q = {port, "127.0.0.1"};
    CHECK(sooc_view_start(&w, &q) == SOOC_EBUSY && !w);
    CHECK_MSG(strstr(sooc_errmsg(), "in use"), "%s", sooc_errmsg());
    printf("  EBUSY -> %s\n", sooc_errmsg());
    q.port = 70000;
    CHECK(sooc_view_start(&w, &q) == SOOC_EINVAL && strstr(sooc_errmsg(), "70000"));
    q.port = 0;
    q.bind = "localhost";
    CHECK(sooc_view_start(&w, &q) == SOOC_EINVAL && strstr(sooc_errmsg(), "IPv4"));

    browser(port);
    sooc_view_stop(v);
    return check_report("test_view");
}
