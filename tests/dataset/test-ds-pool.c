/* test-ds-pool.c - the storage worker pool on a real sd-event loop: jobs are encoded on
 * worker threads, written by one writer, completed on the loop; the queue is bounded
 * (-EAGAIN) and freeing the pool with jobs pending completes every job exactly once; a done
 * no longer counts its own job in flight (the last one sees the pool idle). */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <systemd/sd-event.h>

#include "common/cleanup.h"
#include "dataset/ds.h"
#include "dataset/ds_pool.h"
#include "ds-util.h"
#include "tests/test.h"

#define N_JOBS    8
#define TIMEOUT_S 20

struct job_state {
        int calls;
        int result;
        struct ds_capture c;
};

struct ctx {
        sd_event *event;
        struct ds_pool *pool;
        size_t max_seen; /* the largest ds_pool_in_flight() a done saw, plus done before */
        struct job_state jobs[2 * N_JOBS];
        int done, want;
};

struct job_ref {
        struct ctx *ctx;
        int index;
};

static void on_done(int result, const struct ds_capture *c, const char *error, void *userdata)
{
        struct job_ref *ref = userdata;
        struct job_state *s = &ref->ctx->jobs[ref->index];

        CHECK(result < 0 ? error[0] && c->id == 0 : !error[0] && c->id > 0);
        ref->ctx->max_seen =
                MAX(ref->ctx->max_seen, ds_pool_in_flight(ref->ctx->pool) + ref->ctx->done + 1);
        s->calls++;
        s->result = result;
        s->c = *c;
        if (++ref->ctx->done == ref->ctx->want)
                sd_event_exit(ref->ctx->event, 0);
}

static int on_timeout(sd_event_source *s, uint64_t usec, void *userdata)
{
        fprintf(stderr, "timed out waiting for the storage pool\n");
        exit(1);
}

/* The frame of job i: shapes cycle through mono/RGB and 8/16 bits. */
static void job_frame(struct gn_frame *f, int i)
{
        tu_frame(f, 96 + i, 64, i % 2 ? 3 : 1, (i / 2) % 2 ? 16 : 8, (unsigned)i, false);
}

static int push(struct ds_pool *p, struct ctx *ctx, struct job_ref *refs, int i)
{
        struct gn_frame f;
        struct ds_capture c;
        char cam[16];
        int r;

        job_frame(&f, i);
        snprintf(cam, sizeof(cam), "cam%d", i);
        tu_capture(&c, cam, "l1", i);
        refs[i] = (struct job_ref){ctx, i};
        r = ds_pool_store(p, &f, &c, on_done, &refs[i]);
        CHECK(r == 0 ? f.data == NULL : f.data != NULL); /* taken only when accepted */
        gn_frame_free_data(&f);
        return r;
}

static void check_stored(struct ds *d, const struct job_state *s, int i)
{
        struct gn_frame want, got = {};
        char cam[16];

        snprintf(cam, sizeof(cam), "cam%d", i);
        CHECK_INT(s->calls, 1);
        CHECK_INT(s->result, 0);
        CHECK(strcmp(s->c.camera, cam) == 0);
        CHECK_INT(strlen(s->c.sha256), 64);
        job_frame(&want, i);
        CHECK_INT(ds_load_image(d, s->c.file, &got), 0);
        CHECK(tu_frames_equal(&want, &got));
        gn_frame_free_data(&want);
        gn_frame_free_data(&got);
}

int main(void)
{
        static struct ctx ctx;
        static struct job_ref refs[2 * N_JOBS];
        char *tmp = tu_tmpdir(), path[4200];
        struct ds *d = NULL;
        struct ds_pool *p = NULL;
        int ok = 0;

        snprintf(path, sizeof(path), "%s/ds", tmp);
        CHECK_INT(sd_event_new(&ctx.event), 0);
        CHECK_INT(sd_event_add_time_relative(ctx.event, NULL, CLOCK_MONOTONIC,
                                             TIMEOUT_S * 1000000ull, 0, on_timeout, NULL),
                  0);
        CHECK_INT(ds_create(path, "pool", NULL, &d), 0);
        CHECK_INT(ds_pool_new(ctx.event, d, 0, 4, &p), -EINVAL);
        CHECK_INT(ds_pool_new(ctx.event, d, 2, N_JOBS, &p), 0);
        ctx.pool = p;

        /* a full batch, then back-pressure: completions only arrive on the loop */
        for (int i = 0; i < N_JOBS; i++)
                CHECK_INT(push(p, &ctx, refs, i), 0);
        CHECK_INT(ds_pool_in_flight(p), N_JOBS);
        CHECK_INT(push(p, &ctx, refs, N_JOBS), -EAGAIN);
        ctx.want = N_JOBS;
        CHECK_INT(sd_event_loop(ctx.event), 0);
        CHECK_INT(ds_pool_in_flight(p), 0);
        CHECK_INT(ctx.max_seen, N_JOBS); /* the last done saw the pool idle */
        for (int i = 0; i < N_JOBS; i++)
                check_stored(d, &ctx.jobs[i], i);
        CHECK_INT(ds_count(d), N_JOBS);

        /* free with a batch pending: every job completes once, stored or cancelled */
        for (int i = N_JOBS; i < 2 * N_JOBS; i++)
                CHECK_INT(push(p, &ctx, refs, i), 0);
        p = ds_pool_free(p);
        for (int i = N_JOBS; i < 2 * N_JOBS; i++) {
                CHECK_INT(ctx.jobs[i].calls, 1);
                CHECK(ctx.jobs[i].result == 0 || ctx.jobs[i].result == -ECANCELED);
                ok += ctx.jobs[i].result == 0;
        }
        CHECK_INT(ctx.done, 2 * N_JOBS);
        CHECK_INT(ctx.max_seen, 2 * N_JOBS);
        CHECK_INT(ds_count(d), N_JOBS + ok);
        CHECK_INT(ds_verify(d), 0);
        CHECK_INT(tu_count_tmp(path), 0);

        ds_close(d);
        sd_event_unref(ctx.event);
        tu_rm_rf(tmp);
        free(tmp);
        return 0;
}
