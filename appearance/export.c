/* export.c - ap_export (export.h): the format table, the destination checked (absent or an
 * empty folder), the writer run in a temporary folder beside it, renamed into place; and
 * what the writers share (export_internal.h): the geometry, the images, the scan's cloud.
 *
 * DESIGN: the temporary folder (.NAME.export-XXXXXX beside NAME) is locked (flock on its
 * descriptor) from just after its creation until it is renamed or removed, so that a killed
 * export's folder, whose lock died with it, is told from one being written by a live export:
 * the next export to the same NAME removes the unlocked ones and says so. A folder caught in
 * the instant between its creation and its lock is taken for a killed one's too: the export
 * writing it then fails (ENOENT), which leaves no partial NAME either. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "appearance/export_internal.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds.h"

#define CLOUD_MAX_BYTES (1ul << 31)
#define CLOUD_RECORD    27 /* 6 float32 + 3 uchar */

typedef int (*export_fn)(struct ds *d, const char *ds_dir, const char *dir,
                         const struct ap_export_opts *o, char *err, size_t errlen);

static const struct {
        const char *name;
        export_fn fn;
} formats[] = {
        {"colmap", ap_export_colmap}, {"nerfstudio", ap_export_nerfstudio},
        {"ply", ap_export_ply},       {"rti", ap_export_rti},
        {"gltf", ap_export_gltf},
};

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);

/* 0 when path does not exist or is an empty folder, else -EEXIST or -ENOTDIR. */
static int check_destination(const char *path)
{
        DIR *d = opendir(path);
        struct dirent *e;
        int r = 0;

        if (!d)
                return errno == ENOENT ? 0 : errno == ENOTDIR ? -EEXIST : -errno;
        while (r == 0 && (e = readdir(d)))
                if (strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0)
                        r = -EEXIST;
        closedir(d);
        return r;
}

/* The folder holding out_dir into parent, and ".BASE.export-", the prefix of its temporary
 * folders, into prefix. */
static void temporary_prefix(const char *out_dir, char *parent, size_t plen, char *prefix,
                             size_t xlen)
{
        char dir[4096], base[4096];

        snprintf(dir, sizeof(dir), "%s", out_dir);
        snprintf(base, sizeof(base), "%s", out_dir);
        snprintf(parent, plen, "%s", dirname(dir));
        snprintf(prefix, xlen, ".%s.export-", basename(base));
}

/* Removes the temporary folders of out_dir that no live export holds (left by a killed
 * one); says how many in notes (notes_len bytes) when notes is not NULL. */
static void remove_stale(const char *out_dir, char *notes, size_t notes_len)
{
        char parent[4096], prefix[4200], path[8400];
        struct dirent *e;
        unsigned n = 0;
        DIR *d;

        temporary_prefix(out_dir, parent, sizeof(parent), prefix, sizeof(prefix));
        if (!(d = opendir(parent)))
                return;
        while ((e = readdir(d))) {
                if (strncmp(e->d_name, prefix, strlen(prefix)) != 0 ||
                    strlen(e->d_name) != strlen(prefix) + 6)
                        continue;
                snprintf(path, sizeof(path), "%s/%s", parent, e->d_name);
                int fd = open(path, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
                if (fd >= 0 && flock(fd, LOCK_EX | LOCK_NB) == 0) {
                        ap_remove_tree(path);
                        n++;
                }
                if (fd >= 0)
                        close(fd);
        }
        closedir(d);
        if (n > 0 && notes)
                snprintf(notes, notes_len,
                         "removed %u temporary folder%s of an interrupted export (%s/%sXXXXXX)", n,
                         n > 1 ? "s" : "", parent, prefix);
}

/* Creates and locks the temporary folder of out_dir into tmp. Returns its fd or -errno. */
static int make_temporary(const char *out_dir, char *tmp, size_t len, char *err, size_t errlen)
{
        char parent[4096], prefix[4200];
        int fd, r;

        temporary_prefix(out_dir, parent, sizeof(parent), prefix, sizeof(prefix));
        snprintf(tmp, len, "%s/%sXXXXXX", parent, prefix);
        if (!mkdtemp(tmp)) {
                r = -errno;
                snprintf(err, errlen, "cannot create a temporary folder beside %s: %s", out_dir,
                         strerror(-r));
                return r;
        }
        fd = open(tmp, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0 || flock(fd, LOCK_EX) < 0) {
                r = -errno;
                snprintf(err, errlen, "cannot lock %s: %s", tmp, strerror(-r));
                if (fd >= 0)
                        close(fd);
                ap_remove_tree(tmp);
                return r;
        }
        fchmod(fd, 0755);
        return fd;
}

/* ap_write_folder, the stale temporary folders it removed said in notes (or NULL). */
static int write_folder(const char *out_dir, ap_fill_fn fill, void *ctx, char *notes,
                        size_t notes_len, char *err, size_t errlen)
{
        char tmp[8400];
        int fd, r = check_destination(out_dir);

        if (r < 0) {
                snprintf(err, errlen, "%s: %s", out_dir,
                         r == -EEXIST ? "exists and is not an empty folder" : strerror(-r));
                return r;
        }
        remove_stale(out_dir, notes, notes_len);
        if ((fd = make_temporary(out_dir, tmp, sizeof(tmp), err, errlen)) < 0)
                return fd;
        r = fill(ctx, tmp, err, errlen);
        if (r == 0 && rename(tmp, out_dir) < 0) {
                r = errno == ENOTEMPTY ? -EEXIST : -errno;
                snprintf(err, errlen, "%s: %s", out_dir,
                         r == -EEXIST ? "not empty (written meanwhile)" : strerror(-r));
        }
        if (r < 0)
                ap_remove_tree(tmp);
        close(fd); /* the lock: after the rename or the removal */
        return r < 0 ? r : gn_fsync_parent(out_dir);
}

int ap_write_folder(const char *out_dir, ap_fill_fn fill, void *ctx, char *err, size_t errlen)
{
        return write_folder(out_dir, fill, ctx, NULL, 0, err, errlen);
}

struct dataset_export {
        export_fn fn;
        struct ds *d;
        const char *ds_dir;
        const struct ap_export_opts *o;
};

static int fill_dataset_export(void *ctx, const char *dir, char *err, size_t errlen)
{
        const struct dataset_export *x = ctx;

        return x->fn(x->d, x->ds_dir, dir, x->o, err, errlen);
}

int ap_export(const char *ds_dir, const char *format, const char *out_dir,
              const struct ap_export_opts *o, char *err, size_t errlen)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct ap_export_opts opts = o ? *o : (struct ap_export_opts){0};
        int r;

        if (!ds_dir || !format || !out_dir || !*out_dir)
                return -EINVAL;
        if (opts.notes && opts.notes_len > 0)
                opts.notes[0] = 0;
        for (size_t i = 0; i < sizeof(formats) / sizeof(formats[0]); i++) {
                struct dataset_export x = {formats[i].fn, NULL, ds_dir, &opts};
                if (strcmp(formats[i].name, format) != 0)
                        continue;
                if ((r = ds_open(ds_dir, &d)) < 0) {
                        snprintf(err, errlen, "cannot open dataset %s: %s", ds_dir, strerror(-r));
                        return r;
                }
                x.d = d;
                return write_folder(out_dir, fill_dataset_export, &x, opts.notes, opts.notes_len,
                                    err, errlen);
        }
        snprintf(err, errlen, "unknown format '%s' (colmap, nerfstudio, ply, rti, gltf)", format);
        return -EINVAL;
}

/* ---- shared by the writers ---- */

int exp_geometry(struct ds *d, const struct ap_export_opts *o, struct ap_geometry **ret, char *err,
                 size_t errlen)
{
        return ap_geometry_read(d, o->calibration, o->backends, ret, err, errlen);
}

const char *exp_image_name(const struct ds_capture *row)
{
        const char *s = strrchr(row->file, '/');

        return s ? s + 1 : row->file;
}

int exp_link_images(const struct ap_geometry *g, const char *ds_dir, const char *dir, char *err,
                    size_t errlen)
{
        char images[4200];
        int r = 0;

        snprintf(images, sizeof(images), "%s/images", dir);
        if (mkdir(images, 0755) < 0 && errno != EEXIST) {
                r = -errno;
                snprintf(err, errlen, "cannot create %s: %s", images, strerror(-r));
        }
        for (size_t i = 0; r == 0 && i < g->n_shots; i++) {
                char src[4400], dst[4400], abs[PATH_MAX];
                snprintf(src, sizeof(src), "%s/%s", ds_dir, g->shots[i].row->file);
                snprintf(dst, sizeof(dst), "%s/%s", images, exp_image_name(g->shots[i].row));
                if (link(src, dst) == 0 || errno == EEXIST)
                        continue;
                if (!realpath(src, abs) || symlink(abs, dst) < 0) {
                        r = -errno;
                        snprintf(err, errlen, "cannot link %s into %s: %s", src, images,
                                 strerror(-r));
                }
        }
        return r;
}

FILE *exp_open(const char *dir, const char *name, char *err, size_t errlen)
{
        char path[4300];
        FILE *f;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        f = fopen(path, "we");
        if (!f)
                snprintf(err, errlen, "cannot write %s: %m", path);
        return f;
}

int exp_close(FILE *f, const char *name, char *err, size_t errlen)
{
        int r = fflush(f) == 0 && fsync(fileno(f)) == 0 && !ferror(f) ? 0 : -EIO;

        if (fclose(f) != 0)
                r = -EIO;
        if (r < 0)
                snprintf(err, errlen, "cannot write %s", name);
        return r;
}

void exp_cloud_free(struct exp_cloud *c)
{
        free(c->x);
        free(c->n);
        free(c->rgb);
        *c = (struct exp_cloud){0};
}

/* The vertices of n records at p (little-endian floats: this host's, x86/arm). */
static int cloud_fill(struct exp_cloud *c, const uint8_t *p, size_t n)
{
        c->x = malloc(n * 3 * sizeof(float) + 1);
        c->n = malloc(n * 3 * sizeof(float) + 1);
        c->rgb = malloc(n * 3 + 1);
        if (!c->x || !c->n || !c->rgb)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++, p += CLOUD_RECORD) {
                memcpy(&c->x[3 * i], p, 3 * sizeof(float));
                memcpy(&c->n[3 * i], p + 12, 3 * sizeof(float));
                memcpy(&c->rgb[3 * i], p + 24, 3);
        }
        c->n_points = n;
        return 0;
}

int exp_cloud_read(const char *path, struct exp_cloud *c, char *err, size_t errlen)
{
        static const char props[] = "property float x\nproperty float y\nproperty float z\n"
                                    "property float nx\nproperty float ny\nproperty float nz\n"
                                    "property uchar red\nproperty uchar green\n"
                                    "property uchar blue\n";
        _cleanup_free_ char *buf = NULL;
        const char *v, *end;
        size_t len, n = 0;
        int r;

        *c = (struct exp_cloud){0};
        r = gn_read_file_at(AT_FDCWD, path, CLOUD_MAX_BYTES, (void **)&buf, &len);
        if (r < 0) {
                snprintf(err, errlen, "%s: %s", path, strerror(-r));
                return r;
        }
        end = strstr(buf, "end_header\n");
        v = strstr(buf, "element vertex ");
        if (strncmp(buf, "ply\nformat binary_little_endian 1.0\n", 36) != 0 || !end || !v ||
            v > end || sscanf(v, "element vertex %zu", &n) != 1 ||
            strncmp(strchr(v, '\n') + 1, props, sizeof(props) - 1) != 0 ||
            (size_t)(end + 11 - buf) + n * CLOUD_RECORD > len) {
                snprintf(err, errlen, "%s: not a gonio scan PLY (x y z nx ny nz red green blue)",
                         path);
                return -EBADMSG;
        }
        r = cloud_fill(c, (const uint8_t *)end + 11, n);
        if (r < 0)
                exp_cloud_free(c);
        return r;
}
