/* ds_lp.c - the RTI light files of a session (ds_write_lp, ds_session.h): one .lp file
 * per view listing its single-lamp images with the direction of their light, the format
 * RTI and photometric-stereo tools read (first line the number of images, then
 * "path dx dy dz" per image). The directions are the caller's (rig geometry); this file
 * only selects, groups and writes. */
#include <fcntl.h>
#include <math.h>
#include <string.h>
#include <sys/stat.h>

#include "common/fileio.h"
#include "ds_internal.h"
#include "ds_session.h"

#define LP_DIR "lp"

/* The session's single-lamp base images with their view's turntable and camera arm
 * angles (planned if the row has a plan item, else recorded; to 0.01 degree), by view. */
/* clang-format off */
#define VIEW_ANGLE(col)                                                                            \
        "round(coalesce((SELECT p." col " FROM plan p WHERE p.session = ?1"                        \
        " AND p.seq = captures.plan_seq), " col "), 2)"
#define LP_SQL                                                                                     \
        "SELECT " DS_ROW_COLUMNS ", " VIEW_ANGLE("turntable_deg") " AS vt, "                       \
        VIEW_ANGLE("camera_arm_deg") " AS vc FROM captures WHERE session = ?1"                     \
        " AND kind = 'image' AND bracket = 0 AND laser = 0 AND lamp_bits <> 0"                     \
        " AND (lamp_bits & (lamp_bits - 1)) = 0 ORDER BY camera, vt, vc, id"
/* clang-format on */
#define LP_COL_CAMERA 5  /* in DS_ROW_COLUMNS */
#define LP_COL_VT     25 /* the column of vt (after DS_ROW_COLUMNS); vc follows */

/* One view being written. */
struct lp_view {
        char camera[DS_NAME_MAX];
        double tt, ca; /* NAN: no such axis */
        char *body;    /* the image lines */
        size_t len, n;
        FILE *f; /* writes body */
};

/* A view angle column, NAN for NULL (no such axis). */
static double column_angle(sqlite3_stmt *s, int i)
{
        return sqlite3_column_type(s, i) == SQLITE_NULL ? NAN : sqlite3_column_double(s, i);
}

static bool same_angle(double a, double b)
{
        return isnan(a) ? isnan(b) : a == b;
}

/* Appends "_<prefix><deg>" for an angle that exists, without trailing zeros. */
static void angle_part(char *out, size_t len, const char *prefix, double deg)
{
        char num[32];
        char *end;

        if (isnan(deg))
                return;
        snprintf(num, sizeof(num), "%.2f", deg);
        end = num + strlen(num) - 1;
        while (*end == '0')
                *end-- = 0;
        if (*end == '.')
                *end = 0;
        snprintf(out + strlen(out), len - strlen(out), "_%s%s", prefix, num);
}

/* Creates the directory rel below dir_fd (parent: rel's parent) durably if missing. */
static int make_dir(int dir_fd, const char *rel, const char *parent)
{
        _cleanup_close_ int fd = -EBADF;

        if (mkdirat(dir_fd, rel, 0755) < 0)
                return errno == EEXIST ? 0 : -errno;
        fd = openat(dir_fd, parent, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0 || fsync(fd) < 0)
                return -errno;
        return 0;
}

/* Writes the finished view v into dir (lp/<session>) atomically; frees its lines. */
static int flush_view(struct ds *d, const char *dir, struct lp_view *v, int *files)
{
        _cleanup_free_ char *text = NULL;
        char cam[DS_NAME_MAX], name[512];
        int r = 0;

        if (v->f && fclose(v->f) != 0)
                r = -ENOMEM;
        v->f = NULL;
        if (r == 0 && v->n > 0) {
                ds_name_part(cam, sizeof(cam), v->camera, "camera");
                snprintf(name, sizeof(name), "%s/%s", dir, cam);
                angle_part(name, sizeof(name), "tt", v->tt);
                angle_part(name, sizeof(name), "ca", v->ca);
                strncat(name, ".lp", sizeof(name) - strlen(name) - 1);
                if (asprintf(&text, "%zu\n%s", v->n, v->body) < 0)
                        r = -ENOMEM;
                else
                        r = gn_write_atomic(d->dir_fd, name, text, strlen(text), NULL);
                if (r < 0)
                        ds_fail(d, r, "Failed to write %s: %s", name, strerror(-r));
                else
                        (*files)++;
        }
        free(v->body);
        v->body = NULL;
        v->len = v->n = 0;
        return r;
}

/* Starts view v for the current row of s if it is not v's view (flushing v). */
static int enter_view(struct ds *d, const char *dir, sqlite3_stmt *s, struct lp_view *v, int *files)
{
        const char *cam = (const char *)sqlite3_column_text(s, LP_COL_CAMERA);
        double tt = column_angle(s, LP_COL_VT), ca = column_angle(s, LP_COL_VT + 1);
        int r;

        if (v->f && strcmp(cam, v->camera) == 0 && same_angle(tt, v->tt) && same_angle(ca, v->ca))
                return 0;
        r = flush_view(d, dir, v, files);
        if (r < 0)
                return r;
        snprintf(v->camera, sizeof(v->camera), "%s", cam);
        v->tt = tt;
        v->ca = ca;
        v->f = open_memstream(&v->body, &v->len);
        return v->f ? 0 : -ENOMEM;
}

/* Adds the current row of s to its view, with the direction fn gives. */
static int add_row(struct ds *d, const char *dir, sqlite3_stmt *s, struct lp_view *v, int *files,
                   ds_light_dir_fn fn, void *userdata)
{
        struct ds_capture c;
        double l[3];
        int r;

        r = enter_view(d, dir, s, v, files);
        if (r < 0)
                return r;
        ds_db_read_row(s, &c);
        r = fn(&c, l, userdata);
        if (r != 0)
                return r < 0 ? r : 0;
        fprintf(v->f, "../../%s %.6f %.6f %.6f\n", c.file, l[0], l[1], l[2]);
        v->n++;
        return 0;
}

/* Creates lp/<session part> and sets dir to it. */
static int make_lp_dir(struct ds *d, const char *session, char *dir, size_t len)
{
        char part[DS_NAME_MAX];
        int r;

        ds_name_part(part, sizeof(part), session, "session");
        snprintf(dir, len, "%s/%s", LP_DIR, part);
        r = make_dir(d->dir_fd, LP_DIR, ".");
        if (r == 0)
                r = make_dir(d->dir_fd, dir, LP_DIR);
        return r < 0 ? ds_fail(d, r, "Failed to create %s: %s", dir, strerror(-r)) : 0;
}

int ds_write_lp(struct ds *d, const char *session, ds_light_dir_fn dir_fn, void *userdata)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        struct lp_view v = {};
        char dir[128];
        int files = 0, r, rc = SQLITE_DONE;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !session || !*session || !dir_fn)
                return -EINVAL;
        d->error[0] = 0;
        r = make_lp_dir(d, session, dir, sizeof(dir));
        if (r == 0)
                r = ds_db_prepare(d, LP_SQL, &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, session, -1, SQLITE_STATIC);
        while (r == 0 && (rc = sqlite3_step(s)) == SQLITE_ROW)
                r = add_row(d, dir, s, &v, &files, dir_fn, userdata);
        if (r == 0 && rc != SQLITE_DONE)
                r = ds_db_fail(d, rc, "Failed to read the session's rows");
        if (r == 0)
                r = flush_view(d, dir, &v, &files);
        if (r < 0) {
                if (v.f)
                        fclose(v.f);
                free(v.body);
                return r;
        }
        return files;
}
