/* bench/pipeline.c - captures per second through goniod's capture pipeline at zero motion
 * time, in one process: the renderer of gonio-sim (examples/rigs/sim.yaml, cam0 at 720x480,
 * lamp0 lit, turntable and light arm stepping so that no two frames are alike) feeds the
 * storage pool of goniod (dataset/ds_pool.h: PNG encoder threads, one writer that writes,
 * fsyncs, renames and commits the SQLite row) storing into a real dataset on disk. As in
 * goniod, the next frame renders while the pool encodes and stores the last ones, and a
 * frame waits for room when the pool's bounded queue is full.
 *
 * In the same run, the rate of each stage alone: render; encode on the pool's encoder
 * threads; write + fsync + commit on one thread (ds_store_png into a second dataset). The
 * machine is shared, so the run alternates blocks: each stage alone for a while, then a
 * block of captures through the pipeline (which drains at the block's end), so that a
 * change of load hits all alike. RSS is sampled at 10%, 50% and 100% of the captures.
 * --codecs prints the size and speed of PNG codec choices on rendered frames instead
 * (docs/dataset.md, "Image codec"). Last line: one JSON object. */
#define _XOPEN_SOURCE 700
#include <errno.h>
#include <ftw.h>
#include <getopt.h>
#include <limits.h>
#include <linux/magic.h>
#include <pthread.h>
#include <sqlite3.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/vfs.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "bench/clock.h"
#include "common/cleanup.h"
#include "common/clock.h"
#include "common/rigconf.h"
#include "common/workq.h"
#include "dataset/ds.h"
#include "dataset/ds_png.h"
#include "dataset/ds_pool.h"
#include "drivers/registry.h"
#include "sim/render/internal.h"

#define SAMPLE_FRAMES 8 /* distinct rendered frames the stage and codec runs cycle through */

struct opts {
        long captures;
        const char *dir; /* parent of the temporary datasets */
        unsigned encoders;
        size_t capacity;
        int level;
        int render_threads; /* 0: the renderer's default (one per core) */
        double stage_s;     /* how long each stage runs alone, over all blocks */
        int blocks;
        bool codecs;
        bool keep; /* leave the datasets for inspection */
};

/* Items done, wall time and process CPU time (user + system, all threads) of a stage. */
struct tally {
        long n;
        double secs, cpu;
};

/* What the pipeline run shares between the loop and the render worker. */
struct run {
        const struct opts *o;
        struct sim_scene *scene;
        sd_event *event;
        struct ds_pool *pool;
        struct workq *render_q;
        struct gn_frame job;  /* written by the render worker */
        struct gn_frame next; /* rendered, waiting for room in the pool */
        bool rendering, have_next, block_done;
        long rendered, stored, target;
        double rss_mb[3], sqlite_mb[3]; /* RSS, and SQLite's heap within it (its page cache) */
        int error;
};

static double now(void)
{
        return (double)gn_monotonic_ns() * 1e-9;
}

/* Adds n items done since time t0 and process CPU time cpu0 to t. */
static void tally_add(struct tally *t, long n, double t0, double cpu0)
{
        t->n += n;
        t->secs += now() - t0;
        t->cpu += bench_cpu_self_s() - cpu0;
}

static double per_s(const struct tally *t)
{
        return t->secs > 0 ? t->n / t->secs : 0;
}

static double cpu_ms(const struct tally *t)
{
        return t->n > 0 ? 1e3 * t->cpu / t->n : 0;
}

static double rss_mb(void)
{
        long pages = 0, resident = 0;
        FILE *f = fopen("/proc/self/statm", "re");

        if (f) {
                if (fscanf(f, "%ld %ld", &pages, &resident) != 2)
                        resident = 0;
                fclose(f);
        }
        return (double)resident * (double)sysconf(_SC_PAGESIZE) / (1 << 20);
}

static double peak_rss_mb(void)
{
        struct rusage ru;

        return getrusage(RUSAGE_SELF, &ru) == 0 ? (double)ru.ru_maxrss / 1024 : 0;
}

/* Frame k's pose: lamp0 lit, the turntable and the light arm a step further each frame. */
static struct gn_pose pose_of(long k)
{
        struct gn_pose p = gn_pose_none();

        p.deg[GN_ROLE_TURNTABLE] = (double)((k * 18) % 360);
        p.deg[GN_ROLE_LIGHT_ARM] = (double)((k * 7) % 360);
        p.deg[GN_ROLE_CAMERA_ARM] = 0;
        p.lamps = 1;
        return p;
}

/* Renders frame k with exposure exp (NULL: the rig file's). */
static int render(struct sim_scene *s, long k, const struct sim_expose *exp, struct gn_frame *out)
{
        struct gn_pose p = pose_of(k);
        int r = sim_render(s, &p, 0, exp, (uint64_t)k, out, 0, NULL);

        out->timestamp_ns = gn_realtime_ns();
        return r;
}

static void row_of(const struct gn_frame *f, long k, struct ds_capture *c)
{
        *c = (struct ds_capture){.pose = pose_of(k),
                                 .exposure_us = f->exposure_us,
                                 .gain = f->gain,
                                 .t_request_ns = f->timestamp_ns,
                                 .t_exposure_ns = f->timestamp_ns};
        snprintf(c->session, sizeof(c->session), "bench");
        snprintf(c->camera, sizeof(c->camera), "cam0");
        snprintf(c->lamps, sizeof(c->lamps), "lamp0");
}

static int rm_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
        (void)st, (void)flag, (void)ftw;
        return remove(path);
}

static const char *fs_name(const char *path)
{
        struct statfs sf;

        if (statfs(path, &sf) < 0)
                return "unknown";
        switch (sf.f_type) {
        case EXT4_SUPER_MAGIC:
                return "ext2/3/4";
        case TMPFS_MAGIC:
                return "tmpfs (memory, not a disk!)";
        case XFS_SUPER_MAGIC:
                return "xfs";
        case BTRFS_SUPER_MAGIC:
                return "btrfs";
        case OVERLAYFS_SUPER_MAGIC:
                return "overlayfs";
        default:
                return "other";
        }
}

/* Creates an empty dataset NAME in a new temporary directory under o->dir; path receives
 * the directory. */
static int dataset_new(const struct opts *o, const struct rig_config *rc, const char *name,
                       char *path, size_t len, struct ds **ret)
{
        char ds[PATH_MAX];
        int r;

        snprintf(path, len, "%s/gonio-bench-pipeline-XXXXXX", o->dir);
        if (!mkdtemp(path))
                return -errno;
        snprintf(ds, sizeof(ds), "%s/%s", path, name);
        r = ds_create(ds, name, rc->text, ret);
        if (r >= 0)
                r = ds_set_compression(*ret, o->level);
        return r;
}

/* Removes a temporary directory made by dataset_new and all in it. */
static void dataset_remove(const char *path)
{
        if (path[0])
                (void)nftw(path, rm_entry, 16, FTW_DEPTH | FTW_PHYS);
}

/* --- stages alone --- */

/* Renders for secs seconds (at least n frames, kept in keep[] when keep is not NULL). */
static int render_block(struct sim_scene *s, double secs, long n, struct gn_frame *keep,
                        struct tally *t)
{
        double t0 = now(), cpu0 = bench_cpu_self_s();
        long i = 0;

        for (; i < n || now() - t0 < secs; i++) {
                struct gn_frame f;

                if (render(s, 1000 + t->n + i, NULL, &f) < 0)
                        return -EIO;
                if (keep && i < n)
                        keep[i] = f;
                else
                        gn_frame_free_data(&f);
        }
        tally_add(t, i, t0, cpu0);
        return 0;
}

struct encode_stage {
        const struct gn_frame *frames;
        const struct ds_png_codec *codec;
        double until;
        atomic_long done;
        atomic_int error;
};

static void *encode_worker(void *arg)
{
        struct encode_stage *e = arg;

        while (now() < e->until) {
                long k = atomic_fetch_add(&e->done, 1);
                _cleanup_free_ void *png = NULL;
                size_t len;

                if (ds_png_encode_codec(&e->frames[k % SAMPLE_FRAMES], e->codec, &png, &len) < 0)
                        atomic_store(&e->error, -EIO);
        }
        return NULL;
}

/* Encodes the sample frames with codec on threads threads for secs seconds. */
static int encode_block(const struct gn_frame *frames, const struct ds_png_codec *codec,
                        unsigned threads, double secs, struct tally *t)
{
        struct encode_stage e = {.frames = frames, .codec = codec};
        pthread_t th[16];
        unsigned n = 0;
        double t0 = now(), cpu0 = bench_cpu_self_s();

        e.until = t0 + secs;
        for (; n < threads && n < ELEMENTSOF(th); n++)
                if (pthread_create(&th[n], NULL, encode_worker, &e) != 0)
                        break;
        for (unsigned i = 0; i < n; i++)
                pthread_join(th[i], NULL);
        tally_add(t, atomic_load(&e.done), t0, cpu0);
        return n == 0 ? -EAGAIN : atomic_load(&e.error);
}

/* The sample frames encoded with the store's codec, for the write stage. */
struct encoded {
        void *png[SAMPLE_FRAMES];
        size_t len[SAMPLE_FRAMES];
        const struct gn_frame *shape;
};

/* Stores the encoded sample frames over and over into d for secs seconds with
 * ds_store_png (write, fsync, rename, commit) on this thread. */
static int write_block(struct ds *d, const struct encoded *enc, double secs, struct tally *t)
{
        double t0 = now(), cpu0 = bench_cpu_self_s();
        long i = 0;
        int r = 0;

        for (; r >= 0 && now() - t0 < secs; i++) {
                struct ds_capture c;
                long k = t->n + i;

                row_of(enc->shape, k, &c);
                r = ds_store_png(d, enc->png[k % SAMPLE_FRAMES], enc->len[k % SAMPLE_FRAMES],
                                 enc->shape, &c);
        }
        tally_add(t, i, t0, cpu0);
        if (r < 0)
                fprintf(stderr, "bench/pipeline: store: %s\n", ds_last_error(d));
        return r;
}

/* --- the pipeline --- */

/* Render worker. */
static int render_job(void *userdata)
{
        struct run *p = userdata;

        return render(p->scene, p->rendered, NULL, &p->job);
}

static void on_stored(int result, const struct ds_capture *c, const char *error, void *userdata);
static void render_done(int result, void *userdata);

/* Hands the waiting frame to the pool when it has room, then starts the next render. */
static void feed(struct run *p)
{
        int r = 0;

        if (p->have_next) {
                struct ds_capture c;

                row_of(&p->next, p->rendered - 1, &c);
                r = ds_pool_store(p->pool, &p->next, &c, on_stored, p);
                if (r == -EAGAIN)
                        return; /* the queue is full: wait for a store to finish */
                p->have_next = r < 0;
        }
        if (r >= 0 && !p->rendering && p->rendered < p->target) {
                r = workq_push(p->render_q, render_job, render_done, p, false);
                p->rendering = r >= 0;
        }
        if (r < 0)
                p->error = p->error ?: r;
        p->block_done = p->error < 0 || p->stored == p->target;
}

static void render_done(int result, void *userdata)
{
        struct run *p = userdata;

        p->rendering = false;
        if (result < 0) {
                p->error = p->error ?: result;
                p->block_done = true;
                return;
        }
        p->rendered++;
        p->next = p->job;
        p->have_next = true;
        feed(p);
}

static void on_stored(int result, const struct ds_capture *c, const char *error, void *userdata)
{
        struct run *p = userdata;
        long n = p->o->captures;

        (void)c;
        if (result < 0) {
                fprintf(stderr, "bench/pipeline: store: %s\n", error);
                p->error = p->error ?: result;
                p->block_done = true;
                return;
        }
        p->stored++;
        if (p->stored == (n + 9) / 10 || p->stored == (n + 1) / 2 || p->stored == n) {
                int i = p->stored == n ? 2 : p->stored == (n + 1) / 2;

                p->rss_mb[i] = rss_mb();
                p->sqlite_mb[i] = (double)sqlite3_memory_used() / (1 << 20);
        }
        feed(p);
}

/* Starts the pool on d and the render worker, on a new event loop. */
static int run_start(struct run *p, struct ds *d)
{
        int r = sd_event_new(&p->event);

        if (r >= 0)
                r = ds_pool_new(p->event, d, p->o->encoders, p->o->capacity, &p->pool);
        if (r >= 0)
                r = workq_new(p->event, "render", 1, &p->render_q);
        return r;
}

static void run_stop(struct run *p)
{
        p->render_q = workq_free(p->render_q);
        p->pool = ds_pool_free(p->pool);
        gn_frame_free_data(&p->next);
        p->event = sd_event_unref(p->event);
}

/* Takes captures through render and the pool until target are stored (the pool drained). */
static int pipeline_block(struct run *p, long target, struct tally *t)
{
        double t0 = now(), cpu0 = bench_cpu_self_s();
        long stored = p->stored;
        int r = 0;

        p->target = target;
        p->block_done = false;
        feed(p);
        while (r >= 0 && !p->block_done)
                r = sd_event_run(p->event, UINT64_MAX);
        tally_add(t, p->stored - stored, t0, cpu0);
        return r < 0 ? r : p->error;
}

/* --- codec table --- */

static const char *const filter_names[] = {"none", "sub", "up", "adaptive"};
static const char *const strategy_names[] = {"default", "filtered", "huffman", "rle"};

/* Size of the sample frames encoded with c (checked lossless by decoding), bytes/frame. */
static double codec_size(const struct gn_frame *frames, const struct ds_png_codec *c)
{
        size_t total = 0;

        for (int i = 0; i < SAMPLE_FRAMES; i++) {
                _cleanup_free_ void *png = NULL;
                struct gn_frame back = {};
                size_t len;
                bool same;

                if (ds_png_encode_codec(&frames[i], c, &png, &len) < 0 ||
                    ds_png_decode(png, len, &back) < 0)
                        return -1;
                same = memcmp(back.data, frames[i].data, gn_frame_bytes(&back)) == 0;
                gn_frame_free_data(&back);
                if (!same)
                        return -1;
                total += len;
        }
        return (double)total / SAMPLE_FRAMES;
}

static int codec_rows(const struct gn_frame *frames, double secs)
{
        static const struct ds_png_codec codecs[] = {
                {6, DS_PNG_FILTER_ADAPTIVE, DS_PNG_STRATEGY_FILTERED},
                {1, DS_PNG_FILTER_ADAPTIVE, DS_PNG_STRATEGY_FILTERED},
                {6, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_DEFAULT},
                {3, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_DEFAULT},
                {1, DS_PNG_FILTER_NONE, DS_PNG_STRATEGY_DEFAULT},
                {1, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_DEFAULT},
                {1, DS_PNG_FILTER_UP, DS_PNG_STRATEGY_DEFAULT},
                {1, DS_PNG_FILTER_NONE, DS_PNG_STRATEGY_HUFFMAN},
                {1, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_HUFFMAN},
                {1, DS_PNG_FILTER_NONE, DS_PNG_STRATEGY_RLE},
                {1, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_RLE},
                {1, DS_PNG_FILTER_UP, DS_PNG_STRATEGY_RLE},
                {1, DS_PNG_FILTER_ADAPTIVE, DS_PNG_STRATEGY_RLE},
                {0, DS_PNG_FILTER_NONE, DS_PNG_STRATEGY_DEFAULT},
        };
        double raw = (double)gn_frame_bytes(&frames[0]);

        printf("| level | filter | strategy | KiB/frame | size/raw | CPU ms/frame | raw MB/s |\n");
        printf("|---|---|---|---|---|---|---|\n");
        for (size_t i = 0; i < ELEMENTSOF(codecs); i++) {
                const struct ds_png_codec *c = &codecs[i];
                double size = codec_size(frames, c);
                struct tally t = {};

                if (size < 0 || encode_block(frames, c, 1, secs, &t) < 0)
                        return -1;
                printf("| %d | %s | %s | %.0f | %.3f | %.2f | %.0f |\n", c->level,
                       filter_names[c->filter], strategy_names[c->strategy], size / 1024,
                       size / raw, cpu_ms(&t), raw / (1 << 20) / cpu_ms(&t) * 1e3);
        }
        return 0;
}

/* The codec rows on frames of the rig's exposure, at 16 bits, at gain 8 (noisier) and
 * without sensor noise (smooth). */
static int codec_table(struct sim_scene *s, const struct gn_frame *sample, double secs)
{
        static const struct sim_expose exps[] = {{.bits = 16}, {.gain = 8}, {.no_noise = true}};
        static const char *const names[] = {"16 bits", "gain 8", "no noise"};
        struct gn_frame frames[SAMPLE_FRAMES] = {};
        int r = 0;

        for (size_t e = 0; e <= ELEMENTSOF(exps) && r >= 0; e++) {
                const struct gn_frame *f = e == 0 ? sample : frames;

                for (int i = 0; e > 0 && i < SAMPLE_FRAMES && r >= 0; i++) {
                        gn_frame_free_data(&frames[i]);
                        r = render(s, 1000 + i, &exps[e - 1], &frames[i]);
                }
                if (r < 0)
                        break;
                printf("\n%d rendered %dx%d %s frames, %s (%.0f KiB raw each), 1 thread:\n\n",
                       SAMPLE_FRAMES, f->width, f->height, gn_frame_format(f),
                       e == 0 ? "the rig's exposure" : names[e - 1],
                       (double)gn_frame_bytes(f) / 1024);
                r = codec_rows(f, secs);
        }
        for (int i = 0; i < SAMPLE_FRAMES; i++)
                gn_frame_free_data(&frames[i]);
        return r;
}

/* --- the benchmark --- */

/* Everything a benchmark run holds. */
struct bench {
        const struct opts *o;
        const struct rig_config *rc;
        struct run run;
        struct ds *stage_ds, *run_ds;
        char stage_dir[PATH_MAX], run_dir[PATH_MAX];
        struct ds_png_codec codec;
        struct encoded enc;
        struct tally t[4]; /* render, encode, write alone; the pipeline */
};

static const char *const stage_names[] = {"render", "encode", "write+fsync+commit"};

/* Encodes the sample frames and creates the two datasets. */
static int bench_start(struct bench *b, const struct gn_frame *sample)
{
        int r = 0;

        b->enc.shape = &sample[0];
        for (int i = 0; i < SAMPLE_FRAMES && r >= 0; i++)
                r = ds_png_encode_codec(&sample[i], &b->codec, &b->enc.png[i], &b->enc.len[i]);
        if (r >= 0)
                r = dataset_new(b->o, b->rc, "stage", b->stage_dir, sizeof(b->stage_dir),
                                &b->stage_ds);
        if (r >= 0)
                r = dataset_new(b->o, b->rc, "pipeline", b->run_dir, sizeof(b->run_dir),
                                &b->run_ds);
        if (r >= 0)
                r = run_start(&b->run, b->run_ds);
        return r;
}

static void bench_stop(struct bench *b)
{
        run_stop(&b->run);
        b->stage_ds = ds_close(b->stage_ds);
        b->run_ds = ds_close(b->run_ds);
        if (!b->o->keep) {
                dataset_remove(b->stage_dir);
                dataset_remove(b->run_dir);
        }
        for (int i = 0; i < SAMPLE_FRAMES; i++)
                free(b->enc.png[i]);
}

/* Block after block: each stage alone, then a share of the captures through the pipeline. */
static int bench_blocks(struct bench *b, const struct gn_frame *sample)
{
        const struct opts *o = b->o;
        double secs = o->stage_s / o->blocks;
        int r = 0;

        for (int i = 1; i <= o->blocks && r >= 0; i++) {
                r = render_block(b->run.scene, secs, 1, NULL, &b->t[0]);
                if (r >= 0)
                        r = encode_block(sample, &b->codec, o->encoders, secs, &b->t[1]);
                if (r >= 0)
                        r = write_block(b->stage_ds, &b->enc, secs, &b->t[2]);
                if (r >= 0)
                        r = pipeline_block(&b->run, o->captures * i / o->blocks, &b->t[3]);
        }
        return r;
}

static void report_json(const struct bench *b, int slow, double bound)
{
        const struct run *p = &b->run;
        double rate = per_s(&b->t[3]), slowest = per_s(&b->t[slow]);

        printf("{\"bench\":\"pipeline\",\"captures_per_s\":%.2f,\"slowest_stage_per_s\":%.2f,"
               "\"peak_rss_mb\":%.1f,\"ratio\":%.3f,\"slowest_stage\":\"%s\",\"captures\":%ld,"
               "\"render_per_s\":%.2f,\"encode_per_s\":%.2f,\"write_per_s\":%.2f,"
               "\"cpu_bound_per_s\":%.2f,\"codec\":\"png\",\"level\":%d,\"filter\":\"%s\","
               "\"strategy\":\"%s\",\"encoders\":%u,\"rss_start_mb\":%.1f,\"rss_mid_mb\":%.1f,"
               "\"rss_end_mb\":%.1f}\n",
               rate, slowest, peak_rss_mb(), rate / slowest, stage_names[slow], p->stored,
               per_s(&b->t[0]), per_s(&b->t[1]), per_s(&b->t[2]), bound, b->codec.level,
               filter_names[b->codec.filter], strategy_names[b->codec.strategy], b->o->encoders,
               p->rss_mb[0], p->rss_mb[1], p->rss_mb[2]);
}

static void report(const struct bench *b)
{
        const struct tally *t = b->t;
        long cores = sysconf(_SC_NPROCESSORS_ONLN);
        double bound = (double)cores * 1e3 / (cpu_ms(&t[0]) + cpu_ms(&t[1]) + cpu_ms(&t[2]));
        int slow = 0;

        for (int i = 1; i < 3; i++)
                slow = per_s(&t[i]) < per_s(&t[slow]) ? i : slow;
        printf("render alone: %d threads: %.1f frames/s, %.2f CPU ms/frame\n",
               b->run.scene->threads, per_s(&t[0]), cpu_ms(&t[0]));
        printf("encode alone: %u threads: %.1f frames/s, %.2f CPU ms/frame\n", b->o->encoders,
               per_s(&t[1]), cpu_ms(&t[1]));
        printf("write+fsync+commit alone: 1 thread: %.1f stores/s, %.2f CPU ms/store\n",
               per_s(&t[2]), cpu_ms(&t[2]));
        printf("pipeline: %ld captures, %u encoders, queue %zu: %.1f captures/s, %.2f CPU "
               "ms/capture\n",
               b->run.stored, b->o->encoders, b->o->capacity, per_s(&t[3]), cpu_ms(&t[3]));
        printf("slowest stage alone: %s %.1f/s; end to end / slowest: %.3f\n", stage_names[slow],
               per_s(&t[slow]), per_s(&t[3]) / per_s(&t[slow]));
        printf("CPU bound: the stages' CPU add up to %.2f ms/capture: at most %.1f captures/s "
               "on %ld cores\n",
               cpu_ms(&t[0]) + cpu_ms(&t[1]) + cpu_ms(&t[2]), bound, cores);
        printf("rss: %.1f MB at 10%%, %.1f MB at 50%%, %.1f MB at 100%% of the captures (of "
               "which SQLite's heap: %.1f, %.1f, %.1f MB); peak %.1f MB\n",
               b->run.rss_mb[0], b->run.rss_mb[1], b->run.rss_mb[2], b->run.sqlite_mb[0],
               b->run.sqlite_mb[1], b->run.sqlite_mb[2], peak_rss_mb());
        report_json(b, slow, bound);
}

static int bench(const struct opts *o, const struct rig_config *rc, struct sim_scene *s,
                 const struct gn_frame *sample)
{
        struct bench b = {.o = o, .rc = rc, .run = {.o = o, .scene = s}};
        int r;

        b.codec = ds_png_codec_of_level(o->level);
        r = bench_start(&b, sample);
        printf("datasets: %s, %s on %s\n", b.stage_dir, b.run_dir, fs_name(o->dir));
        if (r >= 0) {
                size_t total = 0;

                for (int i = 0; i < SAMPLE_FRAMES; i++)
                        total += b.enc.len[i];
                printf("png: level %d, filter %s, strategy %s: %.0f KiB/frame (%.3f of raw)\n",
                       o->level, filter_names[b.codec.filter], strategy_names[b.codec.strategy],
                       (double)total / SAMPLE_FRAMES / 1024,
                       (double)total / SAMPLE_FRAMES / (double)gn_frame_bytes(&sample[0]));
                r = bench_blocks(&b, sample);
        }
        bench_stop(&b);
        if (r < 0)
                fprintf(stderr, "bench/pipeline: %s\n", strerror(-r));
        else
                report(&b);
        return r;
}

/* --- main --- */

/* Applies option ch (its argument in optarg) to o. */
static int set_opt(struct opts *o, int ch)
{
        switch (ch) {
        case 'n':
                o->captures = atol(optarg);
                break;
        case 'd':
                o->dir = optarg;
                break;
        case 'e':
                o->encoders = (unsigned)atoi(optarg);
                break;
        case 'c':
                o->capacity = (size_t)atol(optarg);
                break;
        case 'l':
                o->level = atoi(optarg);
                break;
        case 't':
                o->render_threads = atoi(optarg);
                break;
        case 's':
                o->stage_s = atof(optarg);
                break;
        case 'b':
                o->blocks = atoi(optarg);
                break;
        case 'C':
                o->codecs = true;
                break;
        case 'k':
                o->keep = true;
                break;
        default:
                return -EINVAL;
        }
        return 0;
}

static int parse_opts(int argc, char **argv, struct opts *o)
{
        static const struct option longopts[] = {
                {"captures", required_argument, NULL, 'n'},
                {"dir", required_argument, NULL, 'd'},
                {"encoders", required_argument, NULL, 'e'},
                {"capacity", required_argument, NULL, 'c'},
                {"level", required_argument, NULL, 'l'},
                {"render-threads", required_argument, NULL, 't'},
                {"stage-seconds", required_argument, NULL, 's'},
                {"blocks", required_argument, NULL, 'b'},
                {"codecs", no_argument, NULL, 'C'},
                {"keep", no_argument, NULL, 'k'},
                {},
        };
        int ch;

        *o = (struct opts){300, "/var/tmp", 2, 16, DS_PNG_LEVEL_DEFAULT, 0, 3.0, 10, false, false};
        while ((ch = getopt_long(argc, argv, "", longopts, NULL)) != -1)
                if (set_opt(o, ch) < 0)
                        return -EINVAL;
        if (o->captures < 1 || o->encoders < 1 || o->encoders > 16 || o->capacity < 1 ||
            o->level < 0 || o->level > 9 || o->render_threads < 0 || o->stage_s <= 0 ||
            o->blocks < 1 || o->blocks > o->captures || optind != argc)
                return -EINVAL;
        return 0;
}

static int load(const struct opts *o, struct rig_config **rc, struct sim_scene **s)
{
        char err[512] = "";
        int r = rigconf_load(GONIO_SOURCE_DIR "/examples/rigs/sim.yaml", registry_backends, rc, err,
                             sizeof(err));

        if (r >= 0)
                r = sim_scene_new(*rc, s, err, sizeof(err));
        if (r < 0)
                fprintf(stderr, "bench/pipeline: %s\n", err);
        else if (o->render_threads)
                (*s)->threads = o->render_threads;
        return r;
}

int main(int argc, char **argv)
{
        struct opts o;
        struct rig_config *rc = NULL;
        struct sim_scene *s = NULL;
        struct gn_frame sample[SAMPLE_FRAMES] = {};
        struct tally warm = {};
        int r;

        setvbuf(stdout, NULL, _IOLBF, 0);
        if (parse_opts(argc, argv, &o) < 0) {
                fprintf(stderr,
                        "usage: %s [--captures N] [--dir DIR] [--encoders N] "
                        "[--capacity N] [--level 0-9] [--render-threads N] "
                        "[--stage-seconds S] [--blocks N] [--keep] [--codecs]\n",
                        argv[0]);
                return 2;
        }
        r = load(&o, &rc, &s);
        if (r >= 0) /* the sample frames; also warms the renderer up */
                r = render_block(s, 0, SAMPLE_FRAMES, sample, &warm);
        if (r >= 0)
                r = o.codecs ? codec_table(s, sample, o.stage_s / 3) : bench(&o, rc, s, sample);
        for (int i = 0; i < SAMPLE_FRAMES; i++)
                gn_frame_free_data(&sample[i]);
        sim_scene_free(s);
        rigconf_free(rc);
        return r < 0 ? 1 : 0;
}
