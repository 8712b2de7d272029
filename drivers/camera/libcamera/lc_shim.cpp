/* lc_shim.cpp - the C face of libcamera (see lc_shim.h, DESIGN there): the one shared
 * CameraManager, camera lookup, stream configuration, buffers mapped once at open, requests
 * completed on libcamera's thread and handed out through an eventfd, and the camera list for
 * discovery. Every extern "C" entry catches all exceptions and returns -errno. */
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <utility>
#include <string>
#include <vector>

#include <libcamera/libcamera.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <unistd.h>

#include "drivers/camera/libcamera/lc_shim.h"

using namespace libcamera;

namespace
{

/* The process's one CameraManager and its users (lc_shim.h, DESIGN). */
std::mutex cm_lock;
CameraManager *cm;
unsigned cm_users;

int cm_get()
{
        std::lock_guard<std::mutex> g(cm_lock);
        if (!cm) {
                auto m = std::make_unique<CameraManager>();
                int r = m->start();
                if (r < 0)
                        return r;
                cm = m.release();
        }
        cm_users++;
        return 0;
}

void cm_put()
{
        std::lock_guard<std::mutex> g(cm_lock);
        if (--cm_users == 0) {
                cm->stop();
                delete cm;
                cm = nullptr;
        }
}

int fail(char *cause, size_t len, int err, const std::string &msg)
{
        if (cause && len)
                snprintf(cause, len, "%s", msg.c_str());
        return err < 0 ? err : -err;
}

/* Runs f, turning an exception into -ENOMEM / -EIO with its message. */
template <typename F> int guard(char *cause, size_t len, F f)
{
        try {
                return f();
        } catch (const std::bad_alloc &) {
                return fail(cause, len, -ENOMEM, "out of memory");
        } catch (const std::exception &e) {
                return fail(cause, len, -EIO, std::string("libcamera: ") + e.what());
        } catch (...) {
                return fail(cause, len, -EIO, "libcamera: unknown exception");
        }
}

struct mapping {
        void *base = MAP_FAILED;
        size_t size = 0;
        const uint8_t *data = nullptr;
};

std::string fourcc_name(uint32_t fourcc)
{
        return PixelFormat(fourcc).toString();
}

} // namespace

struct lc_cam {
        std::shared_ptr<Camera> camera;
        std::unique_ptr<CameraConfiguration> config;
        std::unique_ptr<FrameBufferAllocator> alloc;
        Stream *stream = nullptr;
        std::vector<std::unique_ptr<Request>> requests;
        std::vector<mapping> maps; /* by request cookie */
        std::mutex lock;           /* guards done */
        /* completed requests, oldest first; capacity reserved for all of them at open, so
         * that complete() never allocates */
        std::vector<Request *> done;
        Request *held = nullptr; /* the request of the frame last handed out */
        int efd = -1;
        bool running = false, acquired = false, have_cm = false;
        int exposure_us = 0;
        double gain = 0;

        ~lc_cam();
        void complete(Request *rq);
        int queue(Request *rq, char *cause, size_t len);
};

/* On libcamera's thread. Cancelled requests (lc_cam_stop) are not handed out. Never throws:
 * done has room for every request and a mutex lock only fails on a misuse. */
void lc_cam::complete(Request *rq)
{
        uint64_t one = 1;

        if (rq->status() == Request::RequestCancelled)
                return;
        std::lock_guard<std::mutex> g(lock);
        done.push_back(rq);
        if (write(efd, &one, sizeof(one)) < 0)
                return; /* cannot overflow: at most one count per buffer */
}

lc_cam::~lc_cam()
{
        if (camera)
                camera->requestCompleted.disconnect(this);
        requests.clear();
        for (auto &m : maps)
                if (m.base != MAP_FAILED)
                        munmap(m.base, m.size);
        alloc.reset();
        if (acquired)
                camera->release();
        camera.reset();
        if (efd >= 0)
                close(efd);
        if (have_cm)
                cm_put();
}

int lc_cam::queue(Request *rq, char *cause, size_t len)
{
        rq->reuse(Request::ReuseBuffers);
        if (exposure_us > 0)
                rq->controls().set(controls::ExposureTime, exposure_us);
        if (gain > 0)
                rq->controls().set(controls::AnalogueGain, (float)gain);
        if ((exposure_us > 0 || gain > 0) && camera->controls().count(&controls::AeEnable))
                rq->controls().set(controls::AeEnable, false);
        int r = camera->queueRequest(rq);
        if (r < 0)
                return fail(cause, len, r, std::string("cannot queue a request: ") + strerror(-r));
        return 0;
}

namespace
{

std::string camera_ids()
{
        std::string s;
        for (const auto &c : cm->cameras())
                s += (s.empty() ? "" : ", ") + c->id();
        return s.empty() ? "none" : s;
}

/* How the rig file names the camera: "'ID'", "of model 'M' at index N" or "at index N". */
std::string which(const char *id, const char *model, int index)
{
        if (id && *id)
                return std::string("'") + id + "'";
        return (model && *model ? std::string("of model '") + model + "' " : std::string()) +
               "at index " + std::to_string(index);
}

std::shared_ptr<Camera> find_camera(const char *id, const char *model, int index)
{
        int n = 0;

        if (id && *id)
                return cm->get(id);
        for (const auto &c : cm->cameras()) {
                const auto m = c->properties().get(properties::Model);
                if (model && *model && (!m || *m != model))
                        continue;
                if (n++ == index)
                        return c;
        }
        return nullptr;
}

/* Picks the first of fourccs the stream offers, at width x height exactly. */
int configure(lc_cam *c, int width, int height, const uint32_t *fourccs, size_t n, char *cause,
              size_t len)
{
        c->config = c->camera->generateConfiguration({StreamRole::StillCapture});
        if (!c->config || c->config->size() != 1)
                return fail(cause, len, -EINVAL, "no still capture configuration");
        StreamConfiguration &sc = c->config->at(0);
        const auto offered = sc.formats().pixelformats();
        const uint32_t *f = std::find_if(fourccs, fourccs + n, [&](uint32_t fcc) {
                return std::count(offered.begin(), offered.end(), PixelFormat(fcc)) > 0;
        });
        if (f == fourccs + n)
                return fail(cause, len, -EINVAL,
                            "offers no format gonio converts (it has " + sc.toString() + ")");
        sc.pixelFormat = PixelFormat(*f);
        sc.size = Size(width, height);
        if (c->config->validate() == CameraConfiguration::Invalid ||
            sc.size != Size(width, height) || sc.pixelFormat != PixelFormat(*f))
                return fail(cause, len, -EINVAL,
                            "cannot give " + Size(width, height).toString() + "-" +
                                    fourcc_name(*f) + " (it offers " + sc.toString() + ")");
        int r = c->camera->configure(c->config.get());
        if (r < 0)
                return fail(cause, len, r, std::string("cannot configure: ") + strerror(-r));
        c->stream = sc.stream();
        return 0;
}

int map_buffer(lc_cam *c, const FrameBuffer &b, char *cause, size_t len)
{
        const FrameBuffer::Plane &p = b.planes()[0];
        mapping m;

        m.size = p.offset + p.length;
        m.base = mmap(nullptr, m.size, PROT_READ, MAP_SHARED, p.fd.get(), 0);
        if (m.base == MAP_FAILED) {
                int err = errno;
                return fail(cause, len, -err, std::string("cannot map a buffer: ") + strerror(err));
        }
        m.data = static_cast<const uint8_t *>(m.base) + p.offset;
        c->maps.push_back(m);
        return 0;
}

/* Allocates the stream's buffers, one request per buffer (cookie: its index), maps them. */
int make_requests(lc_cam *c, char *cause, size_t len)
{
        c->alloc = std::make_unique<FrameBufferAllocator>(c->camera);
        int r = c->alloc->allocate(c->stream);
        if (r < 0)
                return fail(cause, len, r, std::string("cannot allocate buffers: ") + strerror(-r));
        for (const auto &b : c->alloc->buffers(c->stream)) {
                auto rq = c->camera->createRequest(c->requests.size());
                if (!rq)
                        return fail(cause, len, -ENOMEM, "cannot create a request");
                r = rq->addBuffer(c->stream, b.get());
                if (r < 0)
                        return fail(cause, len, r, "cannot add a buffer to a request");
                if ((r = map_buffer(c, *b, cause, len)) < 0)
                        return r;
                c->requests.push_back(std::move(rq));
        }
        return 0;
}

int open_camera(lc_cam *c, const char *id, const char *model, int index, char *cause, size_t len)
{
        int r = cm_get();
        if (r < 0)
                return fail(cause, len, r, std::string("cannot start libcamera: ") + strerror(-r));
        c->have_cm = true;
        c->camera = find_camera(id, model, index);
        if (!c->camera)
                return fail(cause, len, -ENODEV,
                            "no camera " + which(id, model, index) + " (cameras: " + camera_ids() +
                                    ")");
        r = c->camera->acquire();
        if (r < 0)
                return fail(cause, len, r,
                            std::string("cannot acquire ") + c->camera->id() + ": " + strerror(-r));
        c->acquired = true;
        c->camera->requestCompleted.connect(c, &lc_cam::complete);
        return 0;
}

} // namespace

extern "C" int lc_cam_open(const char *id, const char *model, int index, int width, int height,
                           const uint32_t *fourccs, size_t n, struct lc_cam **ret, char *cause,
                           size_t len)
{
        return guard(cause, len, [&]() {
                auto c = std::make_unique<lc_cam>();
                int r;

                if (cause && len)
                        cause[0] = '\0';
                c->efd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK | EFD_SEMAPHORE);
                if (c->efd < 0)
                        return fail(cause, len, -errno, "eventfd failed");
                if ((r = open_camera(c.get(), id, model, index, cause, len)) < 0 ||
                    (r = configure(c.get(), width, height, fourccs, n, cause, len)) < 0 ||
                    (r = make_requests(c.get(), cause, len)) < 0)
                        return r;
                c->done.reserve(c->requests.size());
                *ret = c.release();
                return 0;
        });
}

extern "C" void lc_cam_close(struct lc_cam *cam)
{
        if (!cam)
                return;
        lc_cam_stop(cam);
        guard(nullptr, 0, [&]() {
                delete cam;
                return 0;
        });
}

extern "C" const char *lc_cam_id(const struct lc_cam *cam)
{
        return cam->camera->id().c_str();
}

extern "C" void lc_cam_caps(const struct lc_cam *cam, struct lc_caps *caps)
{
        const ControlInfoMap &ci = cam->camera->controls();
        auto e = ci.find(&controls::ExposureTime);
        auto g = ci.find(&controls::AnalogueGain);

        *caps = lc_caps{};
        if (e != ci.end()) {
                caps->has_exposure = 1;
                caps->exposure_min_us = e->second.min().get<int32_t>();
                caps->exposure_max_us = e->second.max().get<int32_t>();
        }
        if (g != ci.end()) {
                caps->has_gain = 1;
                caps->gain_min = g->second.min().get<float>();
                caps->gain_max = g->second.max().get<float>();
        }
}

extern "C" int lc_cam_start(struct lc_cam *cam, int exposure_us, double gain, char *cause,
                            size_t len)
{
        return guard(cause, len, [&]() {
                struct lc_caps caps;
                int r;

                if (cam->running)
                        return fail(cause, len, -EBUSY, "the camera is streaming");
                lc_cam_caps(cam, &caps);
                if ((exposure_us > 0 && !caps.has_exposure) || (gain > 0 && !caps.has_gain))
                        return fail(cause, len, -EOPNOTSUPP,
                                    std::string("the camera has no ") +
                                            (exposure_us > 0 && !caps.has_exposure
                                                     ? "ExposureTime"
                                                     : "AnalogueGain") +
                                            " control");
                cam->exposure_us = exposure_us;
                cam->gain = gain;
                r = cam->camera->start();
                if (r < 0)
                        return fail(cause, len, r, std::string("cannot start: ") + strerror(-r));
                cam->running = true;
                for (auto &rq : cam->requests)
                        if ((r = cam->queue(rq.get(), cause, len)) < 0) {
                                lc_cam_stop(cam);
                                return r;
                        }
                return 0;
        });
}

extern "C" int lc_cam_fd(const struct lc_cam *cam)
{
        return cam->efd;
}

namespace
{

/* Fills out from a completed request. */
int frame_of(lc_cam *c, Request *rq, lc_frame *out, char *cause, size_t len)
{
        const FrameBuffer *b = rq->buffers().begin()->second;
        const FrameMetadata &md = b->metadata();
        const StreamConfiguration &sc = c->config->at(0);

        if (rq->status() != Request::RequestComplete || md.status != FrameMetadata::FrameSuccess)
                return fail(cause, len, -EIO, "frame " + std::to_string(md.sequence) + " failed");
        *out = lc_frame{};
        out->data = c->maps[rq->cookie()].data;
        out->bytes = md.planes()[0].bytesused;
        out->stride = sc.stride;
        out->width = (int)sc.size.width;
        out->height = (int)sc.size.height;
        out->fourcc = sc.pixelFormat.fourcc();
        out->seq = md.sequence;
        out->sensor_ns = rq->metadata().get(controls::SensorTimestamp).value_or(md.timestamp);
        out->exposure_us = rq->metadata().get(controls::ExposureTime).value_or(0);
        out->gain = rq->metadata().get(controls::AnalogueGain).value_or(0.0f);
        return 0;
}

} // namespace

extern "C" int lc_cam_next(struct lc_cam *cam, struct lc_frame *out, char *cause, size_t len)
{
        return guard(cause, len, [&]() {
                Request *rq = nullptr;
                uint64_t count;
                int r;

                if (!cam->running)
                        return -ENOTCONN;
                if (cam->held &&
                    (r = cam->queue(std::exchange(cam->held, nullptr), cause, len)) < 0)
                        return r;
                {
                        std::lock_guard<std::mutex> g(cam->lock);
                        if (cam->done.empty())
                                return -EAGAIN;
                        rq = cam->done.front();
                        cam->done.erase(cam->done.begin());
                        if (read(cam->efd, &count, sizeof(count)) < 0)
                                count = 0; /* the count matches done: cannot fail */
                }
                cam->held = rq;
                return frame_of(cam, rq, out, cause, len);
        });
}

extern "C" void lc_cam_stop(struct lc_cam *cam)
{
        if (!cam || !cam->running)
                return;
        cam->running = false;
        cam->held = nullptr;
        guard(nullptr, 0, [&]() {
                uint64_t count;

                cam->camera->stop();
                std::lock_guard<std::mutex> g(cam->lock);
                cam->done.clear();
                while (read(cam->efd, &count, sizeof(count)) > 0)
                        ;
                return 0;
        });
}

namespace
{

/* What lc_list() hands out for one camera, owning the strings and arrays the info points to. */
struct listed {
        std::vector<std::string> names;
        std::vector<std::vector<lc_size>> sizes;
        std::vector<lc_format_info> formats;
};

void describe(const StreamFormats &sf, listed &l)
{
        const std::vector<PixelFormat> pfs = sf.pixelformats();

        l.names.reserve(pfs.size()); /* no reallocation: formats point into both */
        l.sizes.reserve(pfs.size());
        for (const PixelFormat &pf : pfs) {
                const SizeRange r = sf.range(pf);
                l.names.push_back(pf.toString());
                l.sizes.emplace_back();
                for (const Size &s : sf.sizes(pf))
                        l.sizes.back().push_back({(int)s.width, (int)s.height});
                l.formats.push_back({pf.fourcc(),
                                     l.names.back().c_str(),
                                     l.sizes.back().data(),
                                     l.sizes.back().size(),
                                     {(int)r.min.width, (int)r.min.height},
                                     {(int)r.max.width, (int)r.max.height}});
        }
}

void list_one(Camera &c, void (*fn)(const lc_camera_info *, void *), void *data)
{
        const auto model = c.properties().get(properties::Model);
        const std::string m = model ? *model : std::string();
        listed l;

        auto config = c.generateConfiguration({StreamRole::StillCapture});
        if (config && config->size() == 1)
                describe(config->at(0).formats(), l);
        const lc_camera_info info = {c.id().c_str(), m.c_str(), l.formats.data(), l.formats.size()};
        fn(&info, data);
}

/* Lists every camera; the shared_ptrs are gone before the caller drops the CameraManager. */
int list_all(void (*fn)(const lc_camera_info *, void *), void *data)
{
        const auto cameras = cm->cameras();
        for (const auto &c : cameras)
                list_one(*c, fn, data);
        return (int)cameras.size();
}

} // namespace

extern "C" int lc_list(void (*fn)(const struct lc_camera_info *info, void *data), void *data,
                       char *cause, size_t len)
{
        int r = guard(cause, len, [&]() { return cm_get(); });

        if (r < 0)
                return fail(cause, len, r, std::string("cannot start libcamera: ") + strerror(-r));
        r = guard(cause, len, [&]() { return list_all(fn, data); });
        cm_put();
        return r;
}
