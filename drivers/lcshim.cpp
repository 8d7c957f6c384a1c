// libcamera behind a C interface (lcshim.h). The project's only C++:
// The call sequence is libcamera's (docs/drivers.md "libcamera"). One CameraManager per process
// (libcamera allows no more), shared by reference count.
#include "lcshim.h"

#include <sys/mman.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <libcamera/libcamera.h>

using namespace libcamera;

namespace {

std::mutex g_mu;
std::unique_ptr<CameraManager> g_cm;
int g_refs = 0;

void set_err(char *err, size_t cap, const std::string &msg) {
    if (err && cap) std::snprintf(err, cap, "%s", msg.c_str());
}

int cm_acquire(char *err, size_t cap) {
    std::lock_guard<std::mutex> lk(g_mu);
    if (g_refs == 0) {
        g_cm = std::make_unique<CameraManager>();
        int r = g_cm->start();
        if (r) {
            g_cm.reset();
            set_err(err, cap, "libcamera: CameraManager::start failed (" + std::to_string(r) + ")");
            return -1;
        }
    }
    g_refs++;
    return 0;
}

void cm_release() {
    std::lock_guard<std::mutex> lk(g_mu);
    if (--g_refs == 0) {
        g_cm->stop();
        g_cm.reset();
    }
}

}  // namespace

struct sooc_lc {
    std::shared_ptr<Camera> cam;
    std::unique_ptr<CameraConfiguration> cfg;
    std::unique_ptr<FrameBufferAllocator> alloc;
    std::vector<std::unique_ptr<Request>> requests;
    std::map<const FrameBuffer *, std::pair<uint8_t *, size_t>> maps;
    Stream *stream = nullptr;
    sooc_lc_frame_cb cb = nullptr;
    void *user = nullptr;
    bool acquired = false, running = false;
    int w = 0, h = 0, stride = 0;
    uint32_t fourcc = 0;

    void onDone(Request *req) {
        if (req->status() == Request::RequestCancelled) return;
        FrameBuffer *fb = req->findBuffer(stream);
        if (fb && cb) {
            auto it = maps.find(fb);
            const FrameMetadata &md = fb->metadata();
            if (it != maps.end() && md.status == FrameMetadata::FrameSuccess) {
                size_t used = md.planes().size() ? md.planes()[0].bytesused : it->second.second;
                cb(user, it->second.first, used, w, h, stride, fourcc, (int64_t)md.timestamp, md.sequence);
            }
        }
        if (running) {
            req->reuse(Request::ReuseBuffers);
            cam->queueRequest(req);
        }
    }
};

extern "C" int sooc_lc_open(sooc_lc **out, const char *which, int w, int h, sooc_lc_frame_cb cb, void *user,
                            char *err, size_t errcap) {
    *out = nullptr;
    try {
        if (cm_acquire(err, errcap)) return -1;
        std::unique_ptr<sooc_lc> c(new sooc_lc);
        std::vector<std::shared_ptr<Camera>> cams;
        {
            std::lock_guard<std::mutex> lk(g_mu);
            cams = g_cm->cameras();
        }
        if (cams.empty()) {
            set_err(err, errcap, "libcamera: no cameras");
            cm_release();
            return -2;
        }
        std::string id = which && *which ? which : "0";
        char *end = nullptr;
        long idx = std::strtol(id.c_str(), &end, 10);
        if (end && *end == '\0') {
            if (idx < 0 || idx >= (long)cams.size()) {
                set_err(err, errcap, "libcamera: camera index " + id + " out of range (" +
                                         std::to_string(cams.size()) + " cameras)");
                cm_release();
                return -2;
            }
            c->cam = cams[(size_t)idx];
        } else {
            std::lock_guard<std::mutex> lk(g_mu);
            c->cam = g_cm->get(id);
        }
        if (!c->cam) {
            set_err(err, errcap, "libcamera: no camera with id '" + id + "'");
            cm_release();
            return -2;
        }
        if (c->cam->acquire()) {
            set_err(err, errcap, "libcamera: camera " + c->cam->id() + " is busy");
            cm_release();
            return -3;
        }
        c->acquired = true;
        c->cfg = c->cam->generateConfiguration({StreamRole::VideoRecording});
        if (!c->cfg || c->cfg->empty()) throw std::runtime_error("no configuration for VideoRecording");
        StreamConfiguration &sc = c->cfg->at(0);
        if (w > 0 && h > 0) sc.size = Size((unsigned)w, (unsigned)h);
        sc.pixelFormat = formats::BGR888;   // bytes R, G, B in memory
        if (c->cfg->validate() == CameraConfiguration::Invalid) throw std::runtime_error("configuration invalid");
        if (sc.pixelFormat != formats::BGR888 && sc.pixelFormat != formats::RGB888 && sc.pixelFormat != formats::YUYV) {
            sc.pixelFormat = formats::YUYV;
            if (c->cfg->validate() == CameraConfiguration::Invalid || sc.pixelFormat != formats::YUYV)
                throw std::runtime_error("camera offers no packed RGB/BGR/YUYV format");
        }
        if (c->cam->configure(c->cfg.get())) throw std::runtime_error("configure failed");
        c->stream = sc.stream();
        c->w = (int)sc.size.width;
        c->h = (int)sc.size.height;
        c->stride = (int)sc.stride;
        c->fourcc = sc.pixelFormat.fourcc();
        c->alloc = std::make_unique<FrameBufferAllocator>(c->cam);
        if (c->alloc->allocate(c->stream) < 0) throw std::runtime_error("buffer allocation failed");
        for (const std::unique_ptr<FrameBuffer> &fb : c->alloc->buffers(c->stream)) {
            const FrameBuffer::Plane &pl = fb->planes()[0];
            size_t len = pl.length;
            void *m = mmap(nullptr, pl.offset + len, PROT_READ, MAP_SHARED, pl.fd.get(), 0);
            if (m == MAP_FAILED) throw std::runtime_error("mmap of a frame buffer failed");
            c->maps[fb.get()] = {static_cast<uint8_t *>(m) + pl.offset, len};
            std::unique_ptr<Request> rq = c->cam->createRequest();
            if (!rq || rq->addBuffer(c->stream, fb.get())) throw std::runtime_error("createRequest failed");
            c->requests.push_back(std::move(rq));
        }
        c->cb = cb;
        c->user = user;
        c->cam->requestCompleted.connect(c.get(), &sooc_lc::onDone);
        *out = c.release();
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errcap, std::string("libcamera: ") + e.what());
        cm_release();
        return -1;
    }
}

extern "C" void sooc_lc_format(const sooc_lc *c, int *w, int *h, int *stride, uint32_t *fourcc, char *id,
                               size_t idcap) {
    *w = c->w;
    *h = c->h;
    *stride = c->stride;
    *fourcc = c->fourcc;
    if (id && idcap) std::snprintf(id, idcap, "%s", c->cam->id().c_str());
}

extern "C" int sooc_lc_start(sooc_lc *c, char *err, size_t errcap) {
    if (c->cam->start()) {
        set_err(err, errcap, "libcamera: start failed");
        return -1;
    }
    c->running = true;
    for (auto &rq : c->requests) {
        if (c->cam->queueRequest(rq.get())) {
            set_err(err, errcap, "libcamera: queueRequest failed");
            return -1;
        }
    }
    return 0;
}

extern "C" void sooc_lc_stop(sooc_lc *c) {
    if (!c || !c->running) return;
    c->running = false;
    c->cam->stop();
}

extern "C" void sooc_lc_close(sooc_lc *c) {
    if (!c) return;
    sooc_lc_stop(c);
    c->cam->requestCompleted.disconnect(c);
    c->requests.clear();
    for (auto &m : c->maps) {
        const FrameBuffer::Plane &pl = m.first->planes()[0];
        munmap(m.second.first - pl.offset, pl.offset + m.second.second);
    }
    c->maps.clear();
    c->alloc.reset();
    if (c->acquired) c->cam->release();
    c->cam.reset();
    delete c;
    cm_release();
}
