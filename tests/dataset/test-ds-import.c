/* test-ds-import.c - frames imported from one dataset into another (ds_import_frame) and
 * the data directory's dark library (ds_library_open, ds_library_add_darks), in real
 * dataset directories: by hard link, by copy (link(2) made to fail with EXDEV, and across
 * a real second file system when a tmpfs can be mounted), exactly once, a corrupted
 * source refused, the library found by a second dataset with the frame's own exposure
 * time, and a writer dying mid-import.
 *
 * linkat and renameat are interposed by defining them in this executable (the dataset
 * library's calls land here and are passed on to libc): `force_exdev` makes linkat fail
 * as across file systems, `crash_at` makes the process _exit right after (or, for
 * "before-rename", right before) the call, as a crash there would. Nothing else is
 * mocked.
 *
 * Usage: test-ds-import CASE (one meson test per case). */
#include <dlfcn.h>
#include <fcntl.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "ds-util.h"
#include "tests/test.h"

#define T_DARK 1700000000123456789ull /* the source dark frame's exposure time */

static bool force_exdev;
static const char *crash_at; /* "link", "before-rename", "rename" */

static void *real(const char *name)
{
        void *f = dlsym(RTLD_NEXT, name);

        CHECK(f);
        return f;
}

int linkat(int from_dir, const char *from, int to_dir, const char *to, int flags)
{
        int r;

        if (force_exdev) {
                errno = EXDEV;
                return -1;
        }
        r = ((int (*)(int, const char *, int, const char *, int))real("linkat"))(from_dir, from,
                                                                                 to_dir, to, flags);
        if (crash_at && strcmp(crash_at, "link") == 0)
                _exit(0);
        return r;
}

int renameat(int from_dir, const char *from, int to_dir, const char *to)
{
        int r;

        if (crash_at && strcmp(crash_at, "before-rename") == 0)
                _exit(0);
        r = ((int (*)(int, const char *, int, const char *))real("renameat"))(from_dir, from,
                                                                              to_dir, to);
        if (crash_at && strcmp(crash_at, "rename") == 0)
                _exit(0);
        return r;
}

/* Two datasets in one scratch directory (the data directory): src has a dark frame of
 * cam0 (and an image), dst a session "s" whose plan item 1 is a dark frame of cam0 at
 * the source frame's pose, item 2 an image. */
struct fixture {
        char *tmp;
        char src_path[4200], dst_path[4200];
        struct ds *src, *dst;
        struct ds_capture dark; /* the source's dark row */
};

static void make_src(struct fixture *fx)
{
        struct ds_capture img;
        struct gn_frame f;

        snprintf(fx->src_path, sizeof(fx->src_path), "%s/src", fx->tmp);
        CHECK_INT(ds_create(fx->src_path, "src", "rig: r\n", &fx->src), 0);
        tu_frame(&f, 16, 12, 1, 16, 7, false);
        tu_capture(&fx->dark, "cam0", "", 3);
        snprintf(fx->dark.session, sizeof(fx->dark.session), "old");
        snprintf(fx->dark.kind, sizeof(fx->dark.kind), "dark");
        fx->dark.pose.lasers = 0;
        fx->dark.t_exposure_ns = T_DARK;
        CHECK_INT(ds_store(fx->src, &f, &fx->dark), 0);
        tu_capture(&img, "cam0", "l1", 4);
        CHECK_INT(ds_store(fx->src, &f, &img), 0);
        gn_frame_free_data(&f);
}

static void make_dst(struct fixture *fx, const char *dir)
{
        struct ds_plan_item items[2] = {{.seq = 1, .shot = 1, .camera = "cam0", .kind = "dark"},
                                        {.seq = 2, .shot = 2, .camera = "cam0", .kind = "image"}};

        snprintf(fx->dst_path, sizeof(fx->dst_path), "%s/dst", dir);
        CHECK_INT(ds_create(fx->dst_path, "dst", "rig: r\n", &fx->dst), 0);
        items[0].pose = fx->dark.pose;
        items[1].pose = fx->dark.pose;
        items[1].pose.lamps = 2;
        CHECK_INT(ds_session_begin(fx->dst, "s", NULL, NULL, NULL, NULL, items, 2), 0);
}

static void setup(struct fixture *fx)
{
        fx->tmp = tu_tmpdir();
        make_src(fx);
        make_dst(fx, fx->tmp);
}

static void teardown(struct fixture *fx)
{
        fx->src = ds_close(fx->src);
        fx->dst = ds_close(fx->dst);
        tu_rm_rf(fx->tmp);
        free(fx->tmp);
}

/* The label of plan item seq of session "s". */
static struct ds_capture item_label(int64_t seq)
{
        struct ds_capture l = {.session = "s", .plan_seq = seq, .kind = "dark"};

        return l;
}

static void file_stat(const char *dataset, const char *file, struct stat *st)
{
        char p[4600];

        snprintf(p, sizeof(p), "%s/%s", dataset, file);
        CHECK(stat(p, st) == 0);
}

static int images(const char *dataset)
{
        char p[4300];

        snprintf(p, sizeof(p), "%s/images", dataset);
        return tu_count(p, "");
}

static void print_problem(const char *problem, void *userdata)
{
        fprintf(stderr, "problem in %s: %s\n", (const char *)userdata, problem);
}

static void check_clean(struct ds *d, const char *what)
{
        CHECK_INT(ds_check(d, print_problem, (void *)what), 0);
}

static int take_row(const struct ds_capture *c, void *userdata)
{
        *(struct ds_capture *)userdata = *c;
        return 0;
}

static struct ds_capture row_of(struct ds *d, int64_t id)
{
        struct ds_capture c = {0};

        CHECK_INT(ds_rows(d, id - 1, 1, take_row, &c), 1);
        CHECK_INT(c.id, id);
        return c;
}

/* Imports the source's dark frame as plan item 1 of dst and checks the new row against
 * it; returns the new row. */
static struct ds_capture import_dark(struct fixture *fx)
{
        struct ds_capture label = item_label(1), c;
        int64_t id;

        label.bracket = 0;
        id = ds_import_frame(fx->dst, fx->src, fx->dark.id, &label);
        CHECK(id > 0);
        c = row_of(fx->dst, id);
        CHECK_STR(c.file, "images/000001_cam0_dark.png"); /* dst's own naming */
        CHECK_STR(c.session, "s");
        CHECK_INT(c.plan_seq, 1);
        CHECK_STR(c.kind, "dark");
        CHECK_STR(c.camera, "cam0");
        CHECK_STR(c.sha256, fx->dark.sha256);
        CHECK_INT(c.size, fx->dark.size);
        CHECK_INT(c.width, 16);
        CHECK_INT(c.height, 12);
        CHECK_STR(c.pixfmt, "mono16");
        CHECK_INT(c.exposure_us, fx->dark.exposure_us);
        CHECK(c.gain == fx->dark.gain);
        CHECK_INT(c.t_request_ns, fx->dark.t_request_ns);
        CHECK_INT(c.t_exposure_ns, T_DARK);
        CHECK(gn_pose_equal(&c.pose, &fx->dark.pose, 0));
        CHECK(c.t_stored_ns >= fx->dark.t_stored_ns);
        return c;
}

static void check_imported(struct fixture *fx, const struct ds_capture *c, bool linked)
{
        struct stat a, b;
        struct ds_session_info info;

        file_stat(fx->src_path, fx->dark.file, &a);
        file_stat(fx->dst_path, c->file, &b);
        CHECK_INT(a.st_ino == b.st_ino && a.st_dev == b.st_dev, linked);
        CHECK_INT(a.st_nlink, linked ? 2 : 1);
        CHECK_INT(ds_session_get(fx->dst, "s", &info), 0);
        CHECK_INT(info.captured, 1);
        ds_session_info_clear(&info);
        CHECK_INT(images(fx->dst_path), 1);
        CHECK_INT(tu_count_tmp(fx->dst_path), 0);
        CHECK_INT(ds_verify(fx->dst), 0);
        check_clean(fx->dst, "dst");
        check_clean(fx->src, "src");
        fx->dst = ds_close(fx->dst); /* and after reopening */
        CHECK_INT(ds_open(fx->dst_path, &fx->dst), 0);
        check_clean(fx->dst, "dst");
}

/* On one file system the image is a hard link to the source's file. */
static void test_link(void)
{
        struct fixture fx = {};
        struct ds_capture c;

        setup(&fx);
        c = import_dark(&fx);
        check_imported(&fx, &c, true);
        teardown(&fx);
}

/* Where link(2) fails with EXDEV the image is copied: another file, the same bytes. */
static void test_copy(void)
{
        struct fixture fx = {};
        struct ds_capture c;

        setup(&fx);
        force_exdev = true;
        c = import_dark(&fx);
        force_exdev = false;
        check_imported(&fx, &c, false);
        teardown(&fx);
}

static char *mounted; /* unmounted at exit, also when a check fails */

static void unmount_at_exit(void)
{
        (void)umount2(mounted, MNT_DETACH);
}

/* dst on a tmpfs, src on the scratch directory's file system: copied for real. Needs
 * mount(2); skipped (77) when tmpfs cannot be mounted or the two are one file system. */
static void test_xdev(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        static char mnt[4200];
        struct stat a, b;

        fx.tmp = tu_tmpdir();
        snprintf(mnt, sizeof(mnt), "%s/mnt", fx.tmp);
        CHECK(mkdir(mnt, 0700) == 0);
        if (mount("tmpfs", mnt, "tmpfs", MS_NOSUID | MS_NODEV, "size=4m,mode=0700") < 0) {
                fprintf(stderr, "cannot mount tmpfs on %s (%m): skipped\n", mnt);
                tu_rm_rf(fx.tmp);
                exit(TEST_SKIP);
        }
        mounted = mnt;
        atexit(unmount_at_exit);
        make_src(&fx);
        make_dst(&fx, mnt);
        CHECK(stat(fx.src_path, &a) == 0 && stat(fx.dst_path, &b) == 0 && a.st_dev != b.st_dev);
        c = import_dark(&fx);
        check_imported(&fx, &c, false);
        fx.dst = ds_close(fx.dst);
        CHECK(umount2(mnt, MNT_DETACH) == 0);
        teardown(&fx);
}

/* A plan item is imported once: the second import is -EEXIST before any file is placed;
 * a missing source row, an item the plan lacks and a bad kind leave nothing either. */
static void test_once(void)
{
        struct fixture fx = {};
        struct ds_capture label = item_label(1);

        setup(&fx);
        CHECK(ds_import_frame(fx.dst, fx.src, fx.dark.id, &label) > 0);
        force_exdev = true; /* the copy path checks first too */
        for (int i = 0; i < 2; i++) {
                CHECK_INT(ds_import_frame(fx.dst, fx.src, fx.dark.id, &label), -EEXIST);
                CHECK_STR_CONTAINS(ds_last_error(fx.dst), "plan item 1 of session 's' is row 1");
                force_exdev = false;
        }
        label.plan_seq = 9;
        CHECK_INT(ds_import_frame(fx.dst, fx.src, fx.dark.id, &label), -EINVAL);
        label.plan_seq = 2;
        snprintf(label.kind, sizeof(label.kind), "bogus");
        CHECK_INT(ds_import_frame(fx.dst, fx.src, fx.dark.id, &label), -EINVAL);
        CHECK_INT(ds_import_frame(fx.dst, fx.src, 99, &label), -ENOENT);
        CHECK_INT(ds_count(fx.dst), 1);
        CHECK_INT(images(fx.dst_path), 1);
        CHECK_INT(tu_count_tmp(fx.dst_path), 0);
        check_clean(fx.dst, "dst");
        teardown(&fx);
}

/* A source file that no longer matches its row's checksum is refused, by link and by
 * copy: -EBADMSG, no row, no file, the source's link count as before. */
static void test_corrupt(void)
{
        struct fixture fx = {};
        struct ds_capture label = item_label(1);
        char p[4600];
        struct stat st;
        int fd;

        setup(&fx);
        snprintf(p, sizeof(p), "%s/%s", fx.src_path, fx.dark.file);
        fd = open(p, O_WRONLY);
        CHECK(fd >= 0 && pwrite(fd, "X", 1, 60) == 1 && close(fd) == 0); /* same size */
        for (int copy = 0; copy < 2; copy++) {
                force_exdev = copy;
                CHECK_INT(ds_import_frame(fx.dst, fx.src, fx.dark.id, &label), -EBADMSG);
                CHECK_STR_CONTAINS(ds_last_error(fx.dst), "does not match the checksum");
                CHECK_INT(ds_count(fx.dst), 0);
                CHECK_INT(images(fx.dst_path), 0);
                CHECK_INT(tu_count_tmp(fx.dst_path), 0);
                CHECK(stat(p, &st) == 0 && st.st_nlink == 1);
        }
        force_exdev = false;
        check_clean(fx.dst, "dst");
        CHECK_INT(ds_verify(fx.src), 1);
        teardown(&fx);
}

/* Session "old" of src gives its dark frame to the library; a session of another dataset
 * finds it there with its own exposure time (so a maximum age still applies), imports it
 * and gives nothing back; adding again adds nothing. */
static void test_library(void)
{
        struct ds_capture label = {.session = "s", .kind = "dark"};
        struct fixture fx = {};
        struct ds *lib = NULL;
        int64_t id, mine;

        setup(&fx);
        CHECK_INT(ds_library_open(fx.tmp, false, &lib), -ENOENT);
        CHECK_INT(ds_library_open(fx.tmp, true, &lib), 0);
        CHECK_STR(ds_name(lib), DS_LIBRARY);
        CHECK_INT(ds_library_add_darks(lib, fx.src, "other"), 0);
        CHECK_INT(ds_library_add_darks(lib, fx.src, "old"), 1);
        CHECK_INT(ds_library_add_darks(lib, fx.src, "old"), 0);
        CHECK_INT(ds_library_add_darks(lib, fx.src, NULL), 0);
        CHECK_INT(ds_library_add_darks(lib, lib, NULL), -EINVAL);
        lib = ds_close(lib);

        CHECK_INT(ds_library_open(fx.tmp, false, &lib), 0); /* a later session */
        id = ds_find_dark(lib, "cam0", fx.dark.exposure_us, fx.dark.gain, T_DARK);
        CHECK(id > 0);
        CHECK_STR(row_of(lib, id).session, DS_LIBRARY_SESSION);
        CHECK_INT(row_of(lib, id).plan_seq, 0);
        CHECK_INT(ds_find_dark(lib, "cam0", fx.dark.exposure_us, fx.dark.gain, T_DARK + 1), 0);
        CHECK_INT(ds_find_dark(fx.dst, "cam0", fx.dark.exposure_us, fx.dark.gain, 0), 0);
        mine = ds_import_frame(fx.dst, lib, id, &label); /* outside the plan */
        CHECK(mine > 0);
        CHECK_INT(ds_find_dark(fx.dst, "cam0", fx.dark.exposure_us, fx.dark.gain, T_DARK), mine);
        lib = ds_close(lib);
        CHECK_INT(ds_library_open(fx.tmp, true, &lib), 0);
        CHECK_INT(ds_library_add_darks(lib, fx.dst, "s"), 0); /* the same frame */
        CHECK_INT(ds_count(lib), 1);
        check_clean(lib, "library");
        check_clean(fx.dst, "dst");
        check_clean(fx.src, "src");
        lib = ds_close(lib);
        teardown(&fx);
}

/* A child imports plan item 1 and dies at crash point `at`, having left a link, a
 * renamed copy or a temporary file and no row. */
static void crash_child(struct fixture *fx, const char *at)
{
        struct ds_capture label = item_label(1);
        pid_t pid;
        int status;

        fx->dst = ds_close(fx->dst); /* no SQLite connection crosses the fork */
        fx->src = ds_close(fx->src);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                if (ds_open(fx->dst_path, &fx->dst) < 0 || ds_open(fx->src_path, &fx->src) < 0)
                        _exit(2);
                force_exdev = strcmp(at, "link") != 0;
                crash_at = at;
                (void)ds_import_frame(fx->dst, fx->src, fx->dark.id, &label);
                _exit(3); /* not reached */
        }
        CHECK(waitpid(pid, &status, 0) == pid);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
        CHECK_INT(ds_open(fx->src_path, &fx->src), 0);
}

/* After the crash the item is pending; the next writer removes what the import left and
 * imports it once; both datasets are clean. */
static void test_crash(void)
{
        static const char *const points[] = {"link", "rename", "before-rename"};

        for (size_t i = 0; i < ELEMENTSOF(points); i++) {
                struct ds_capture label = item_label(1);
                struct fixture fx = {};
                struct stat st;

                setup(&fx);
                crash_child(&fx, points[i]);
                CHECK_INT(images(fx.dst_path), 1); /* the orphan or the temporary file */
                CHECK_INT(ds_open(fx.dst_path, &fx.dst), 0);
                CHECK_INT(ds_count(fx.dst), 0);
                CHECK_INT(ds_check(fx.dst, NULL, NULL), 1);
                CHECK(ds_import_frame(fx.dst, fx.src, fx.dark.id, &label) > 0);
                CHECK_INT(ds_count(fx.dst), 1);
                CHECK_INT(images(fx.dst_path), 1);
                CHECK_INT(tu_count_tmp(fx.dst_path), 0);
                file_stat(fx.src_path, fx.dark.file, &st);
                CHECK_INT(st.st_nlink, 2); /* the orphan link is gone, the new one stays */
                check_clean(fx.dst, "dst");
                check_clean(fx.src, "src");
                fprintf(stderr, "crash at %s: resumed clean\n", points[i]);
                teardown(&fx);
        }
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"link", test_link},   {"copy", test_copy},       {"xdev", test_xdev},
                {"once", test_once},   {"corrupt", test_corrupt}, {"library", test_library},
                {"crash", test_crash},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
