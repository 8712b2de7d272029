/* test-ds-tmpfs.c - the dataset store on a really full disk: a 2 MiB tmpfs is filled
 * by storing noisy frames until a store fails; the failure must be -ENOSPC with no
 * row, no temp file and no image left behind, and storing must work again once space
 * is freed. Needs mount(2) (root); exits 77 (skipped) when tmpfs cannot be mounted. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/mount.h>
#include <unistd.h>

#include "dataset/ds.h"
#include "ds-util.h"
#include "tests/test.h"

#define MAX_STORES 64

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
        return 0;
}
