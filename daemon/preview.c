/* preview.c - the live view's pictures (see preview.h).
 *
 * DESIGN: per camera, at most one picture is being encoded. A frame that arrives for a
 * watched camera whose last picture is at least 1/fps old, with none in the encoder, is
 * downscaled on the loop (PREVIEW_MAX_WIDTH, the mean of up to 2x2 samples per output pixel,
 * 16-bit samples to their top 8 bits) into a job for the worker (common/workq.h, one thread,
 * one slot per camera, niced), which encodes it with libjpeg; the JPEG comes back on the loop and
 * goes to the callback. Every other frame is dropped, so the loop's cost is bounded by fps
 * per camera whatever the capture rate, and the worker never queues.
 *
 * Peeks: a timer ticks at PREVIEW_IDLE_FPS while any camera is watched; at each tick a
 * watched camera that has had no frame for a tick gets one rig_peek, unless a session or a
 * scan is active (they own the cameras and their captures feed the view) or the rig is in
 * fault. A peek is one capture job on the camera's bus; it does not lock the rig. */
#include <errno.h>
#include <setjmp.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include <jpeglib.h> /* after stdio.h: it needs FILE and size_t */
#include <systemd/sd-event.h>

#include "common/cleanup.h"
#include "common/clock.h"
#include "common/log.h"
#include "common/workq.h"
#include "manager.h"
#include "preview.h"

/* A downscaled frame on its way through the encoder, and its JPEG on the way back. */
struct pv_job {
        struct preview *p;
        int cam;
        int width, height, channels;
        uint8_t *pix; /* 8-bit, rows packed */
        unsigned char *jpeg;
        unsigned long jpeg_len;
};

struct pv_cam {
        struct preview *p;
        unsigned viewers;
        bool encoding;
        uint64_t last_ns; /* CLOCK_MONOTONIC of the last frame taken for encoding */
};

struct preview {
        struct manager *m;
        struct workq *worker;
        sd_event_source *tick;
        uint64_t period_ns;
        preview_fn fn;
        void *ud;
        unsigned watched; /* viewers of all cameras */
        struct pv_cam cams[RIG_MAX_CAMERAS];
};

static struct pv_job *job_free(struct pv_job *j)
{
        if (j) {
                free(j->pix);
                free(j->jpeg);
                free(j);
        }
        return NULL;
}

/* Sample (x, y, channel ch) of f as 8 bits. */
static inline unsigned sample8(const struct gn_frame *f, int x, int y, int ch)
{
        const uint8_t *row = f->data + (size_t)y * f->stride;

        if (f->bits == 16)
                return ((const uint16_t *)row)[x * f->channels + ch] >> 8;
        return row[x * f->channels + ch];
}

/* Downscales f by the whole factor k into j (allocated here). Returns 0 or -ENOMEM. */
static int downscale(const struct gn_frame *f, int k, struct pv_job *j)
{
        int h = k / 2; /* the second sample of each block, when it has one */

        j->width = f->width / k;
        j->height = f->height / k;
        j->channels = f->channels;
        j->pix = malloc((size_t)j->width * j->height * j->channels);
        if (!j->pix)
                return -ENOMEM;
        for (int y = 0; y < j->height; y++)
                for (int x = 0; x < j->width; x++)
                        for (int c = 0; c < j->channels; c++) {
                                int sx = x * k, sy = y * k;
                                unsigned v = sample8(f, sx, sy, c) + sample8(f, sx + h, sy, c) +
                                             sample8(f, sx, sy + h, c) +
                                             sample8(f, sx + h, sy + h, c);
                                j->pix[((size_t)y * j->width + x) * j->channels + c] = v / 4;
                        }
        return 0;
}

/* libjpeg's errors, which would exit() by default: back to encode() instead. */
struct pv_error {
        struct jpeg_error_mgr mgr;
        jmp_buf back;
};

static void on_jpeg_error(j_common_ptr cinfo)
{
        char msg[JMSG_LENGTH_MAX];

        cinfo->err->format_message(cinfo, msg);
        log_warning("preview: libjpeg: %s", msg);
        longjmp(((struct pv_error *)cinfo->err)->back, 1);
}

/* Encodes j->pix as JPEG into j->jpeg (worker thread, lowered to PREVIEW_NICE at its first
 * job so that it yields to the session's threads). Returns 0 or -EIO. */
static int encode(void *userdata)
{
        static _Thread_local bool niced;
        struct pv_job *j = userdata;
        struct jpeg_compress_struct cinfo;
        struct pv_error err;

        if (!niced && setpriority(PRIO_PROCESS, gettid(), PREVIEW_NICE) < 0)
                log_info("preview: cannot lower the encoder's priority (%m): it runs at goniod's");
        niced = true;
        cinfo.err = jpeg_std_error(&err.mgr);
        err.mgr.error_exit = on_jpeg_error;
        if (setjmp(err.back)) {
                jpeg_destroy_compress(&cinfo);
                return -EIO;
        }
        jpeg_create_compress(&cinfo);
        jpeg_mem_dest(&cinfo, &j->jpeg, &j->jpeg_len);
        cinfo.image_width = j->width;
        cinfo.image_height = j->height;
        cinfo.input_components = j->channels;
        cinfo.in_color_space = j->channels == 3 ? JCS_RGB : JCS_GRAYSCALE;
        jpeg_set_defaults(&cinfo);
        jpeg_set_quality(&cinfo, PREVIEW_QUALITY, TRUE);
        cinfo.dct_method = JDCT_IFAST;
        jpeg_start_compress(&cinfo, TRUE);
        while (cinfo.next_scanline < cinfo.image_height) {
                JSAMPROW row = j->pix + (size_t)cinfo.next_scanline * j->width * j->channels;
                jpeg_write_scanlines(&cinfo, &row, 1);
        }
        jpeg_finish_compress(&cinfo);
        jpeg_destroy_compress(&cinfo);
        return j->jpeg && j->jpeg_len > 0 ? 0 : -EIO;
}

static void on_encoded(int result, void *userdata)
{
        struct pv_job *j = userdata;
        struct preview *p = j->p;

        p->cams[j->cam].encoding = false;
        if (result >= 0 && p->cams[j->cam].viewers > 0)
                p->fn(p->ud, j->cam, j->jpeg, j->jpeg_len, j->width, j->height);
        else if (result < 0 && result != -ECANCELED)
                log_warning_errno(result, "preview: encoding a picture failed: %m");
        job_free(j);
}

void preview_frame(struct preview *p, int cam, const struct gn_frame *frame)
{
        struct pv_cam *pc = &p->cams[cam];
        uint64_t now = gn_monotonic_ns();
        struct pv_job *j;
        int k = (frame->width + PREVIEW_MAX_WIDTH - 1) / PREVIEW_MAX_WIDTH, r;

        if (pc->viewers == 0 || pc->encoding || now - pc->last_ns < p->period_ns || !frame->data ||
            (frame->channels != 1 && frame->channels != 3) || k < 1 || frame->height < k)
                return;
        j = calloc(1, sizeof(*j));
        if (!j)
                return;
        *j = (struct pv_job){.p = p, .cam = cam};
        r = downscale(frame, MAX(k, 1), j);
        if (r >= 0)
                r = workq_push(p->worker, encode, on_encoded, j, false);
        if (r < 0) {
                job_free(j);
                return;
        }
        pc->encoding = true;
        /* on the fps grid while frames keep coming, so the rate is fps, not a bit below */
        pc->last_ns = now - pc->last_ns < 2 * p->period_ns ? pc->last_ns + p->period_ns : now;
}

static void on_peeked(struct rig *rig, int result, struct gn_frame *frame, const char *msg,
                      void *userdata)
{
        struct pv_cam *pc = userdata;

        if (result < 0)
                log_debug("preview: %s", msg);
        else
                preview_frame(pc->p, pc - pc->p->cams, frame);
}

/* Peeks the watched cameras that had no frame for a tick, while nobody else drives them. */
static int on_tick(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct preview *p = userdata;
        struct manager *m = p->m;
        uint64_t now = gn_monotonic_ns(),
                 idle_ns = MAX(p->period_ns, 1000000000ULL / PREVIEW_IDLE_FPS);

        if (!session_active(m->session) && !scan_active(m->scan) &&
            strcmp(rig_state(m->rig), "fault") != 0)
                for (size_t i = 0; i < rig_config(m->rig)->n_cameras; i++) {
                        struct pv_cam *pc = &p->cams[i];
                        if (pc->viewers > 0 && !pc->encoding && now - pc->last_ns >= idle_ns)
                                (void)rig_peek(m->rig, i, &(struct cam_request){0}, on_peeked, pc);
                }
        (void)sd_event_source_set_time_relative(es, idle_ns / 1000);
        return 0;
}

static void on_tap(void *userdata, int cam, const struct gn_frame *frame)
{
        preview_frame(userdata, cam, frame);
}

void preview_watch(struct preview *p, int cam, bool on)
{
        p->cams[cam].viewers += on ? 1 : -1;
        p->watched += on ? 1 : -1;
        if (on && p->watched == 1) /* the first viewer gets a peek at once */
                (void)sd_event_source_set_time_relative(p->tick, 0);
        (void)sd_event_source_set_enabled(p->tick, p->watched ? SD_EVENT_ON : SD_EVENT_OFF);
}

int preview_new(struct manager *m, unsigned fps, preview_fn fn, void *ud, struct preview **ret)
{
        struct preview *p = calloc(1, sizeof(*p));
        int r;

        if (!p)
                return -ENOMEM;
        *p = (struct preview){.m = m, .fn = fn, .ud = ud};
        p->period_ns = 1000000000ULL / CLAMP(fps, 1u, (unsigned)PREVIEW_MAX_FPS);
        for (size_t i = 0; i < RIG_MAX_CAMERAS; i++)
                p->cams[i].p = p;
        r = workq_new(m->event, "preview", RIG_MAX_CAMERAS, &p->worker);
        if (r >= 0)
                r = sd_event_add_time_relative(m->event, &p->tick, CLOCK_MONOTONIC, 0, 1000,
                                               on_tick, p);
        if (r >= 0)
                r = sd_event_source_set_enabled(p->tick, SD_EVENT_OFF);
        if (r < 0) {
                preview_free(p);
                return r;
        }
        (void)sd_event_source_set_description(p->tick, "preview-peek");
        capture_set_tap(m->capture, on_tap, p);
        *ret = p;
        return 0;
}

struct preview *preview_free(struct preview *p)
{
        if (!p)
                return NULL;
        if (p->m->capture)
                capture_set_tap(p->m->capture, NULL, NULL);
        for (size_t i = 0; p->m->rig && i < rig_config(p->m->rig)->n_cameras; i++)
                rig_peek_cancel(p->m->rig, i);
        p->watched = 0;
        memset(p->cams, 0, sizeof(p->cams)); /* the encodes canceled below are not delivered */
        p->worker = workq_free(p->worker);
        sd_event_source_disable_unref(p->tick);
        free(p);
        return NULL;
}
