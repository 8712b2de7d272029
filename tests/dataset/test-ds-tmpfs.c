/* test-ds-tmpfs.c - the dataset store on a really full disk: a 2 MiB tmpfs is filled
 * by storing noisy frames until a store fails; the failure must be -ENOSPC with no
 * row, no temp file and no image left behind, and storing must work again once space
 * is freed. Then the storage pool fills it with two-camera captures (a small and a
 * large frame each): every frame's completion must say exactly what the index holds
 * (committed with its id, or failed with a message and nothing recorded), also when
 * one camera's frame is stored and the other's does not fit.
 * Needs mount(2) (root); exits 77 (skipped) when tmpfs cannot be mounted. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/mount.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "dataset/ds.h"
#include "dataset/ds_pool.h"
#include "ds-util.h"
#include "tests/test.h"

#define MAX_STORES 64
#define POOL_PAIRS 24 /* two-camera captures pushed to the pool */

static void make_ballast(const char *path, size_t bytes)
{
        static char block[4096];
        FILE *f = fopen(path, "w");

        CHECK(f);
        memset(block, 0x5a, sizeof(block));
        for (size_t n = 0; n < bytes; n += sizeof(block))
                CHECK(fwrite(block, 1, sizeof(block), f) == sizeof(block));
        CHECK(fclose(f) == 0);
}

static int store_noise(struct ds *d, int i, struct ds_capture *c)
{
        struct gn_frame f;
        int r;

        tu_frame(&f, 128, 128, 3, 16, (unsigned)i, false); /* ~98 KiB of PNG */
        tu_capture(c, "cam0", "l1,l2", i);
        r = ds_store(d, &f, c);
        gn_frame_free_data(&f);
        return r;
}

static void check_consistent(struct ds *d, const char *path, int64_t rows)
{
        char images[4200];

        snprintf(images, sizeof(images), "%s/images", path);
        CHECK_INT(ds_count(d), rows);
        CHECK_INT(tu_count(images, ""), rows);
        CHECK_INT(tu_count_tmp(path), 0);
        CHECK_INT(ds_verify(d), 0);
}

static void fill_and_recover(const char *mnt)
{
        char path[4200], ballast[4200];
        struct ds *d = NULL;
        struct ds_capture c;
        int64_t stored = 0;
        int r = 0;

        snprintf(path, sizeof(path), "%s/ds", mnt);
        snprintf(ballast, sizeof(ballast), "%s/ballast", mnt);
        make_ballast(ballast, 512 << 10);
        CHECK_INT(ds_create(path, "full", "rig: tmpfs-rig\n", &d), 0);
        while (stored < MAX_STORES && (r = store_noise(d, (int)stored, &c)) == 0)
                stored++;
        CHECK_INT(r, -ENOSPC);
        CHECK(stored > 2);
        check_consistent(d, path, stored);

        CHECK(unlink(ballast) == 0);
        CHECK_INT(store_noise(d, 100, &c), 0);
        CHECK_INT(c.id, stored + 1);
        check_consistent(d, path, stored + 1);
        d = ds_close(d);
        CHECK_INT(ds_open(path, &d), 0);
        check_consistent(d, path, stored + 1);
        ds_close(d);
}

/* What the pool reported for one frame. */
struct outcome {
        int calls, result;
        struct ds_capture c;
        char error[256];
};

struct pool_ctx {
        sd_event *event;
        struct outcome out[2 * POOL_PAIRS];
        int done;
};

struct pool_ref {
        struct pool_ctx *ctx;
        int i;
};

static void on_stored(int result, const struct ds_capture *c, const char *error, void *userdata)
{
        struct pool_ref *ref = userdata;
        struct outcome *o = &ref->ctx->out[ref->i];

        o->calls++;
        o->result = result;
        o->c = *c;
        snprintf(o->error, sizeof(o->error), "%s", error);
        ref->ctx->done++;
}

/* Frame i of the pool phase: even = cam0, small; odd = cam1, ~98 KiB of PNG. */
static void pool_push(struct ds_pool *p, struct pool_ctx *ctx, struct pool_ref *refs, int i)
{
        struct gn_frame f;
        struct ds_capture c;

        if (i % 2)
                tu_frame(&f, 128, 128, 3, 16, (unsigned)i, false);
        else
                tu_frame(&f, 16, 16, 1, 8, (unsigned)i, false);
        tu_capture(&c, i % 2 ? "cam1" : "cam0", "l1", i);
        refs[i] = (struct pool_ref){ctx, i};
        CHECK_INT(ds_pool_store(p, &f, &c, on_stored, &refs[i]), 0);
        gn_frame_free_data(&f);
}

static int find_row(const struct ds_capture *c, void *userdata)
{
        *(struct ds_capture *)userdata = *c;
        return 0;
}

/* The outcome of a frame agrees with the index; returns 1 if it was committed. */
static int check_outcome(struct ds *d, const struct outcome *o)
{
        struct ds_capture row = {};

        CHECK_INT(o->calls, 1);
        if (o->result < 0) {
                CHECK_INT(o->result, -ENOSPC);
                CHECK_INT(o->c.id, 0);
                CHECK(o->error[0]);
                return 0;
        }
        CHECK(o->c.id > 0 && !o->error[0]);
        CHECK_INT(ds_rows(d, o->c.id - 1, 1, find_row, &row), 1);
        CHECK_INT(row.id, o->c.id);
        CHECK_STR(row.file, o->c.file);
        CHECK_STR(row.sha256, o->c.sha256);
        return 1;
}

static void pool_fill(const char *mnt)
{
        static struct pool_ctx ctx;
        static struct pool_ref refs[2 * POOL_PAIRS];
        char path[4200];
        struct ds *d = NULL, *reader = NULL;
        struct ds_pool *p = NULL;
        int stored = 0, partial = 0;

        snprintf(path, sizeof(path), "%s/pool", mnt);
        CHECK_INT(ds_create(path, "pool", NULL, &d), 0);
        CHECK_INT(sd_event_new(&ctx.event), 0);
        CHECK_INT(ds_pool_new(ctx.event, d, 2, 2, &p), 0);
        for (int k = 0; k < POOL_PAIRS; k++) { /* one capture of two cameras at a time */
                pool_push(p, &ctx, refs, 2 * k);
                pool_push(p, &ctx, refs, 2 * k + 1);
                while (ctx.done < 2 * k + 2)
                        CHECK(sd_event_run(ctx.event, 10 * 1000000) >= 0);
        }
        CHECK_INT(ds_open(path, &reader), 0);
        for (int i = 0; i < 2 * POOL_PAIRS; i++)
                stored += check_outcome(reader, &ctx.out[i]);
        for (int k = 0; k < POOL_PAIRS; k++)
                partial += ctx.out[2 * k].result == 0 && ctx.out[2 * k + 1].result < 0;
        fprintf(stderr, "%d of %d frames stored, %d captures partly\n", stored, 2 * POOL_PAIRS,
                partial);
        CHECK(partial > 0 && stored < 2 * POOL_PAIRS);
        p = ds_pool_free(p);
        check_consistent(reader, path, stored);
        ds_close(reader);
        ds_close(d);
        sd_event_unref(ctx.event);
}

static char *mounted; /* unmounted at exit, also when a check fails */

static void unmount_at_exit(void)
{
        if (umount2(mounted, MNT_DETACH) < 0 || rmdir(mounted) < 0)
                fprintf(stderr, "cannot clean up %s: %m\n", mounted);
        free(mounted);
}

int main(void)
{
        char *mnt = tu_tmpdir();

        if (mount("tmpfs", mnt, "tmpfs", MS_NOSUID | MS_NODEV, "size=2m,mode=0700") < 0) {
                fprintf(stderr, "cannot mount tmpfs on %s (%m): skipped\n", mnt);
                rmdir(mnt);
                free(mnt);
                return TEST_SKIP;
        }
        mounted = mnt;
        CHECK(atexit(unmount_at_exit) == 0);
        fill_and_recover(mnt);
        pool_fill(mnt);
        return 0;
}
