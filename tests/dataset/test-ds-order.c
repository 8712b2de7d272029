/* test-ds-order.c - the durability order of one ds_store, observed at the system
 * calls: the image file is fsynced before it is renamed to its name, the rename is
 * made durable (fsync of images/) before the row reaches the index, and the row
 * reaches the index (SQLite's write of the WAL frame, the commit) last. The same for
 * one ds_import_frame by hard link: link, fsync of images/, commit.
 *
 * fsync, fdatasync, rename, renameat, linkat and pwrite64 are interposed by defining them in
 * this executable: the dataset library's calls and libsqlite3's calls (through its
 * PLT) both land here, are recorded with the path of their file, and are passed on to
 * libc (dlsym RTLD_NEXT). Nothing is mocked: every call still happens. */
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "ds-util.h"
#include "tests/test.h"

#define MAX_EVENTS 256

enum ev_kind { EV_FSYNC, EV_RENAME, EV_WAL_WRITE, EV_LINK };

struct event {
        enum ev_kind kind;
        char path[PATH_MAX];
};

static struct event events[MAX_EVENTS];
static int n_events;
static bool recording;

static void record(enum ev_kind kind, const char *path)
{
        if (!recording)
                return;
        CHECK(n_events < MAX_EVENTS);
        events[n_events].kind = kind;
        snprintf(events[n_events].path, sizeof(events[n_events].path), "%s", path);
        n_events++;
}

/* The path of an open fd ("" if unknown). */
static void fd_path(int fd, char out[PATH_MAX])
{
        char link[64];
        ssize_t n;

        snprintf(link, sizeof(link), "/proc/self/fd/%d", fd);
        n = readlink(link, out, PATH_MAX - 1);
        out[n > 0 ? n : 0] = 0;
}

static bool ends_with(const char *s, const char *suffix)
{
        size_t a = strlen(s), b = strlen(suffix);

        return a >= b && strcmp(s + a - b, suffix) == 0;
}

static void *real(const char *name)
{
        void *f = dlsym(RTLD_NEXT, name);

        CHECK(f);
        return f;
}

int fsync(int fd)
{
        char p[PATH_MAX];

        fd_path(fd, p);
        record(EV_FSYNC, p);
        return ((int (*)(int))real("fsync"))(fd);
}

int fdatasync(int fd)
{
        char p[PATH_MAX];

        fd_path(fd, p);
        record(EV_FSYNC, p);
        return ((int (*)(int))real("fdatasync"))(fd);
}

int rename(const char *from, const char *to)
{
        record(EV_RENAME, to);
        return ((int (*)(const char *, const char *))real("rename"))(from, to);
}

int renameat(int from_dir, const char *from, int to_dir, const char *to)
{
        record(EV_RENAME, to);
        return ((int (*)(int, const char *, int, const char *))real("renameat"))(from_dir, from,
                                                                                 to_dir, to);
}

int linkat(int from_dir, const char *from, int to_dir, const char *to, int flags)
{
        record(EV_LINK, to);
        return ((int (*)(int, const char *, int, const char *, int))real("linkat"))(
                from_dir, from, to_dir, to, flags);
}

ssize_t pwrite64(int fd, const void *buf, size_t len, off_t off)
{
        char p[PATH_MAX];

        if (recording) {
                fd_path(fd, p);
                if (ends_with(p, "-wal"))
                        record(EV_WAL_WRITE, p);
        }
        return ((ssize_t(*)(int, const void *, size_t, off_t))real("pwrite64"))(fd, buf, len, off);
}

/* Index of the first event of kind whose path ends with suffix, or -1. */
static int find(enum ev_kind kind, const char *suffix)
{
        for (int i = 0; i < n_events; i++)
                if (events[i].kind == kind && ends_with(events[i].path, suffix))
                        return i;
        return -1;
}

static void dump(void)
{
        static const char *const names[] = {"fsync", "rename", "wal-write", "link"};

        for (int i = 0; i < n_events; i++)
                fprintf(stderr, "  %2d %-9s %s\n", i, names[events[i].kind], events[i].path);
}

/* The second store of d: fsync of the file < rename < fsync of images/ < commit. */
static void check_store(struct ds *d, const struct gn_frame *f)
{
        struct ds_capture c;
        int i_sync, i_rename, i_dir, i_wal;

        tu_capture(&c, "cam0", "l1", 1);
        n_events = 0;
        recording = true;
        CHECK_INT(ds_store(d, f, &c), 0);
        recording = false;
        dump();
        CHECK_STR(c.file, "images/000002_cam0_l1_laser.png");
        i_sync = find(EV_FSYNC, "/images/000002_cam0_l1_laser.png.tmp");
        i_rename = find(EV_RENAME, "000002_cam0_l1_laser.png");
        i_dir = find(EV_FSYNC, "/images");
        i_wal = find(EV_WAL_WRITE, "/index.sqlite-wal");
        fprintf(stderr, "file fsync %d, rename %d, dir fsync %d, commit %d\n", i_sync, i_rename,
                i_dir, i_wal);
        CHECK(i_sync >= 0 && i_rename >= 0 && i_dir >= 0 && i_wal >= 0);
        CHECK(i_sync < i_rename);
        CHECK(i_rename < i_dir);
        CHECK(i_dir < i_wal);
}

/* An import of row 1 of src into the new dataset at path, by hard link: link < fsync of
 * images/ < commit. */
static void check_import(struct ds *src, const char *path)
{
        struct ds_capture label = {.session = ""};
        struct ds *dst = NULL;
        int i_link, i_dir, i_wal;

        CHECK_INT(ds_create(path, "order-import", NULL, &dst), 0);
        n_events = 0;
        recording = true;
        CHECK_INT(ds_import_frame(dst, src, 1, &label), 1);
        recording = false;
        dump();
        i_link = find(EV_LINK, "000001_cam0_l1.png");
        i_dir = find(EV_FSYNC, "/images");
        i_wal = find(EV_WAL_WRITE, "/index.sqlite-wal");
        fprintf(stderr, "link %d, dir fsync %d, commit %d\n", i_link, i_dir, i_wal);
        CHECK(i_link >= 0 && i_dir >= 0 && i_wal >= 0);
        CHECK(i_link < i_dir);
        CHECK(i_dir < i_wal);
        ds_close(dst);
}

int main(void)
{
        char *tmp = tu_tmpdir(), path[4200];
        struct ds *d = NULL;
        struct ds_capture c;
        struct gn_frame f;

        snprintf(path, sizeof(path), "%s/ds", tmp);
        CHECK_INT(ds_create(path, "order", "rig: order\n", &d), 0);
        tu_frame(&f, 64, 48, 3, 8, 1, false);
        tu_capture(&c, "cam0", "l1", 0);
        CHECK_INT(ds_store(d, &f, &c), 0); /* the first store also takes the writer's lock */
        check_store(d, &f);
        snprintf(path, sizeof(path), "%s/imported", tmp);
        check_import(d, path);

        gn_frame_free_data(&f);
        ds_close(d);
        tu_rm_rf(tmp);
        free(tmp);
        return 0;
}
