/* calfile.c - the calibration file's machinery (calfile.h): open and check the document,
 * replace one section keeping the others, the never-worse rule, the atomic write, small YAML
 * writers and readers shared by the sections; and the turntable, laser and lamp sections
 * with cal_file_read. The camera section is in camera_file.c. */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "calib/calfile.h"
#include "common/cleanup.h"
#include "common/fileio.h"

/* The kinds of sections cal_file_read knows: each must be a mapping of named sections. */
static const char *const tops[] = {"cameras", "turntables", "lasers", "lamps"};

void cal_utc_now(char out[32])
{
        time_t now = time(NULL);
        struct tm tm;

        strftime(out, 32, "%Y-%m-%dT%H:%M:%SZ", gmtime_r(&now, &tm));
}

void cal_yaml_str(FILE *f, const char *key, const char *s)
{
        fprintf(f, "%s: \"", key);
        for (; *s; s++) {
                if (*s == '"' || *s == '\\')
                        fputc('\\', f);
                fputc(*s, f);
        }
        fprintf(f, "\"\n");
}

void cal_yaml_vec(FILE *f, const char *key, const double *v, size_t n)
{
        fprintf(f, "%s: [", key);
        for (size_t i = 0; i < n; i++)
                fprintf(f, "%s%.10g", i ? ", " : "", v[i]);
        fprintf(f, "]\n");
}

void cal_yaml_board(FILE *f, const struct cal_board *b)
{
        fprintf(f, "board: { type: %s, squares: [%d, %d], square_mm: %.9g",
                b->type == CAL_BOARD_CHARUCO ? "charuco" : "chessboard", b->squares_x, b->squares_y,
                b->square_mm);
        if (b->type == CAL_BOARD_CHARUCO)
                fprintf(f, ", marker_mm: %.9g", b->marker_mm);
        fprintf(f, " }\n");
}

int cal_yaml_read_board(struct yconf *yc, struct fy_node *m, struct cal_board *b)
{
        struct fy_node *bm = yconf_get(m, "board");
        char type[16] = "";
        double sq[2] = {0, 0};
        int r;

        if (!bm)
                return yconf_error(yc, m, "board", "missing");
        if ((r = yconf_str_req(yc, bm, "type", type, sizeof(type))) < 0 ||
            (r = yconf_doubles(yc, bm, "squares", sq, 2, 2, NULL)) < 0 ||
            (r = yconf_double(yc, bm, "square_mm", 0, 1e4, &b->square_mm)) < 0 ||
            (r = yconf_double(yc, bm, "marker_mm", 0, 1e4, &b->marker_mm)) < 0)
                return r;
        if (strcmp(type, "charuco") != 0 && strcmp(type, "chessboard") != 0)
                return yconf_error(yc, yconf_get(bm, "type"), "board.type",
                                   "expected chessboard or charuco");
        for (int i = 0; i < 2; i++) /* whole and within an int: a cast beyond is undefined */
                if (!(sq[i] >= 0 && sq[i] <= 1000) || sq[i] != floor(sq[i]))
                        return yconf_error(yc, yconf_get(bm, "squares"), "board.squares",
                                           "expected two whole numbers from 0 to 1000");
        b->type = !strcmp(type, "charuco") ? CAL_BOARD_CHARUCO : CAL_BOARD_CHESSBOARD;
        b->squares_x = (int)sq[0];
        b->squares_y = (int)sq[1];
        return 0;
}

int cal_yaml_numbers(struct yconf *yc, struct fy_node *m, const char *const *keys, double *const *v,
                     size_t n)
{
        for (size_t i = 0; i < n; i++) {
                int r = yconf_double(yc, m, keys[i], -1e12, 1e12, v[i]);

                if (r <= 0)
                        return r < 0 ? r : yconf_error(yc, m, keys[i], "missing");
        }
        return 0;
}

/* A number array of exactly n, required. */
static int need_vec(struct yconf *yc, struct fy_node *m, const char *key, double *v, size_t n)
{
        int r = yconf_doubles(yc, m, key, v, n, n, NULL);

        return r == 0 ? yconf_error(yc, m, key, "missing") : r < 0 ? r : 0;
}

/* An integer, required. */
static int need_int(struct yconf *yc, struct fy_node *m, const char *key, long *v)
{
        int r = yconf_int(yc, m, key, 0, INT_MAX, v); /* counts: each fits an int */

        return r == 0 ? yconf_error(yc, m, key, "missing") : r < 0 ? r : 0;
}

/* ---- the document ---- */

/* Records why the file is malformed at node (key) and returns -EBADMSG. */
static int malformed(struct yconf *yc, struct fy_node *node, const char *key, const char *why)
{
        yconf_error(yc, node, key, "%s", why);
        return -EBADMSG;
}

int cal_file_open(struct yconf *yc, const char *path, bool create, char *err, size_t errlen)
{
        struct fy_node *root;
        char format[64] = "";
        int r = yconf_open(yc, path, err, errlen);

        if (r == -ENOENT && create)
                r = yconf_open_string(yc, path, "format: " CAL_FILE_FORMAT "\n", err, errlen);
        if (r < 0)
                return r == -EINVAL ? -EBADMSG : r;
        root = yconf_root(yc);
        if (!root || fy_node_get_type(root) != FYNT_MAPPING)
                return malformed(yc, root, NULL, "not a calibration file: expected a mapping");
        if (yconf_str(yc, root, "format", format, sizeof(format)) < 0 ||
            strcmp(format, CAL_FILE_FORMAT) != 0)
                return malformed(yc, yconf_get(root, "format") ?: root, "format",
                                 "not a calibration file: expected 'format: " CAL_FILE_FORMAT "'");
        for (size_t i = 0; i < ELEMENTSOF(tops); i++) {
                struct fy_node *t = yconf_get(root, tops[i]);

                if (t && fy_node_get_type(t) != FYNT_MAPPING)
                        return malformed(yc, t, tops[i], "expected a mapping of named sections");
        }
        return 0;
}

/* -EEXIST when the file's section old is better than the new result s. */
static int keep_better(struct yconf *yc, struct fy_node *old, const struct cal_section *s,
                       const char *path)
{
        double rms = -1;
        long count = 0;

        if (yconf_double(yc, old, s->rms_key, 0, 1e6, &rms) <= 0 || !CAL_WORSE(s->rms, rms))
                return 0;
        yconf_int(yc, old, s->count_key, 0, 1L << 40, &count);
        snprintf(yc->err, yc->errlen,
                 "kept the calibration of %s in %s (RMS %.3f %s from %ld %s): the new one is "
                 "worse (RMS %.3f %s from %ld %s); force to replace it",
                 s->what, path, rms, s->unit, count, s->count_what, s->rms, s->unit, s->count,
                 s->count_what);
        return -EEXIST;
}

/* The mapping top of the document, added when missing. */
static struct fy_node *top_mapping(struct yconf *yc, const char *top)
{
        struct fy_node *root = yconf_root(yc), *t = yconf_get(root, top), *key;

        if (t)
                return t;
        t = fy_node_create_mapping(yc->doc);
        key = fy_node_create_scalar_copy(yc->doc, top, FY_NT);
        if (!t || !key || fy_node_mapping_append(root, key, t) < 0)
                return NULL;
        return t;
}

/* What emit writes for obj, as malloc'd text. */
static char *emit_text(cal_emit_fn emit, const void *obj)
{
        char *text = NULL;
        size_t len = 0;
        FILE *f = open_memstream(&text, &len);

        if (!f)
                return NULL;
        emit(f, obj);
        if (fclose(f) != 0) {
                free(text);
                return NULL;
        }
        return text;
}

static int put_section(struct yconf *yc, const struct cal_section *s, cal_emit_fn emit,
                       const void *obj)
{
        struct fy_node *top = top_mapping(yc, s->top), *node = NULL, *key;
        struct fy_node_pair *pair;
        char *text = emit_text(emit, obj);

        /* the document keeps pointers into its source text: hand it text to own */
        if (top && text)
                node = fy_node_build_from_malloc_string(yc->doc, text, FY_NT);
        if (!node) /* text is not freed: whether libfyaml took it on failure is unsaid */
                return -ENOMEM;
        pair = fy_node_mapping_lookup_pair_by_string(top, s->name, -1);
        if (pair)
                return fy_node_pair_set_value(pair, node) < 0 ? -ENOMEM : 0;
        key = fy_node_create_scalar_copy(yc->doc, s->name, FY_NT);
        if (!key || fy_node_mapping_append(top, key, node) < 0)
                return -ENOMEM;
        return 0;
}

int cal_file_put(const char *path, const struct cal_section *s, cal_emit_fn emit, const void *obj,
                 bool force, char *err, size_t errlen)
{
        _cleanup_(cal_file_closep) struct yconf yc = {0};
        _cleanup_free_ char *out = NULL;
        struct fy_node *old;
        int r;

        r = cal_file_open(&yc, path, true, err, errlen);
        if (r < 0)
                return r;
        old = yconf_get(yconf_get(yconf_root(&yc), s->top), s->name);
        if (old && !force && (r = keep_better(&yc, old, s, path)) < 0)
                return r;
        r = put_section(&yc, s, emit, obj);
        if (r < 0)
                return r;
        out = fy_emit_document_to_string(yc.doc, FYECF_MODE_BLOCK | FYECF_WIDTH_INF);
        if (!out)
                return -ENOMEM;
        r = gn_write_atomic(AT_FDCWD, path, out, strlen(out), NULL);
        if (r < 0)
                snprintf(err, errlen, "cannot write %s: %s", path, strerror(-r));
        return r;
}

/* ---- turntables.<camera> ---- */

static void solved_dataset(FILE *f, const char *solved, const char *dataset)
{
        char now[32];

        if (!solved[0])
                cal_utc_now(now);
        fprintf(f, "solved: %s\n", solved[0] ? solved : now);
        cal_yaml_str(f, "dataset", dataset);
}

static void turntable_yaml(FILE *f, const void *obj)
{
        const struct cal_file_turntable *t = obj;
        const struct cal_turntable *tt = &t->tt;

        solved_dataset(f, t->solved, t->dataset);
        cal_yaml_board(f, &t->board);
        cal_yaml_vec(f, "R", tt->R, 9);
        cal_yaml_vec(f, "t", tt->t, 3);
        cal_yaml_vec(f, "axis", tt->axis, 3);
        cal_yaml_vec(f, "origin", tt->origin, 3);
        fprintf(f, "rms_px: %.4f\ncircle_rms_mm: %.4f\ntilt_deg: %.4f\nspan_deg: %.3f\n",
                tt->rms_px, tt->circle_rms_mm, tt->tilt_deg, tt->span_deg);
        fprintf(f, "views_used: %d\nviews_given: %d\n", tt->n_used, tt->n_views);
}

int cal_turntable_write(const char *path, const struct cal_file_turntable *t, bool force, char *err,
                        size_t errlen)
{
        char what[DS_NAME_MAX + 32];

        snprintf(what, sizeof(what), "the turntable seen by camera %s", t->camera);
        return cal_file_put(path,
                            &(struct cal_section){"turntables", t->camera, what, "rms_px", "px",
                                                  t->tt.rms_px, "views_used", "views",
                                                  t->tt.n_used},
                            turntable_yaml, t, force, err, errlen);
}

static int turntable_from_yaml(struct yconf *yc, struct fy_node *m, const char *name,
                               struct cal_file_turntable *out)
{
        struct cal_turntable *tt = &out->tt;
        static const char *const keys[] = {"rms_px", "circle_rms_mm", "tilt_deg", "span_deg"};
        double *const v[] = {&tt->rms_px, &tt->circle_rms_mm, &tt->tilt_deg, &tt->span_deg};
        long used = 0, given = 0;
        int r;

        snprintf(out->camera, sizeof(out->camera), "%s", name);
        if ((r = yconf_str(yc, m, "solved", out->solved, sizeof(out->solved))) < 0 ||
            (r = yconf_str(yc, m, "dataset", out->dataset, sizeof(out->dataset))) < 0 ||
            (r = cal_yaml_read_board(yc, m, &out->board)) < 0 ||
            (r = need_vec(yc, m, "R", tt->R, 9)) < 0 || (r = need_vec(yc, m, "t", tt->t, 3)) < 0 ||
            (r = need_vec(yc, m, "axis", tt->axis, 3)) < 0 ||
            (r = need_vec(yc, m, "origin", tt->origin, 3)) < 0 ||
            (r = cal_yaml_numbers(yc, m, keys, v, ELEMENTSOF(keys))) < 0 ||
            (r = need_int(yc, m, "views_used", &used)) < 0 ||
            (r = need_int(yc, m, "views_given", &given)) < 0)
                return r;
        tt->n_used = (int)used;
        tt->n_views = (int)given;
        return 0;
}

/* ---- lasers.<laser> ---- */

static void laser_yaml(FILE *f, const void *obj)
{
        const struct cal_file_laser *l = obj;

        solved_dataset(f, l->solved, l->dataset);
        fprintf(f, "camera: %s\n", l->camera);
        cal_yaml_vec(f, "n", l->plane.n, 3);
        fprintf(f, "d: %.10g\n", l->plane.d);
        fprintf(f, "rms_mm: %.4f\nspread_mm: %.3f\npoints: %ld\ninliers: %ld\n", l->rms_mm,
                l->spread_mm, l->points, l->inliers);
        fprintf(f, "views_used: %d\nviews_given: %d\n", l->n_used, l->n_views);
        fprintf(f, "axis_angle_deg: %.4f\naxis_dist_mm: %.4f\n", l->axis_angle_deg,
                l->axis_dist_mm);
}

/* The file's turntable section of camera into out. */
static int file_turntable(const char *path, const char *camera, struct cal_file_turntable *out,
                          char *err, size_t errlen)
{
        _cleanup_free_ struct cal_file *f = malloc(sizeof(*f));
        const struct cal_file_turntable *t;
        int r;

        if (!f)
                return -ENOMEM;
        r = cal_file_read(path, f, err, errlen);
        if (r < 0 && r != -ENOENT)
                return r;
        t = r < 0 ? NULL : cal_file_turntable(f, camera);
        if (!t) {
                snprintf(err, errlen,
                         "%s has no turntable calibration of camera %s, which the laser plane "
                         "is moved into the turntable frame with: calibrate the turntable first "
                         "(gonioctl calibrate turntable)",
                         path, camera);
                return -ENOENT;
        }
        *out = *t;
        return 0;
}

int cal_laser_write(const char *path, const char *name, const char *camera,
                    const struct cal_laser *l, const char *dataset, bool force, char *err,
                    size_t errlen)
{
        struct cal_file_laser fl = {.rms_mm = l->rms_mm,
                                    .spread_mm = l->spread_mm,
                                    .points = (long)l->points,
                                    .inliers = (long)l->inliers,
                                    .n_views = l->n_views,
                                    .n_used = l->n_used};
        struct cal_file_turntable t;
        char what[DS_NAME_MAX + 16];
        int r = file_turntable(path, camera, &t, err, errlen);

        if (r < 0)
                return r;
        snprintf(fl.name, sizeof(fl.name), "%s", name);
        snprintf(fl.camera, sizeof(fl.camera), "%s", camera);
        snprintf(fl.dataset, sizeof(fl.dataset), "%s", dataset ?: "");
        cal_plane_to_turntable(&l->plane, &t.tt, &fl.plane);
        cal_laser_vs_axis(&l->plane, &t.tt, &fl.axis_angle_deg, &fl.axis_dist_mm);
        snprintf(what, sizeof(what), "laser %s", name);
        return cal_file_put(path,
                            &(struct cal_section){"lasers", name, what, "rms_mm", "mm", l->rms_mm,
                                                  "views_used", "views", l->n_used},
                            laser_yaml, &fl, force, err, errlen);
}

static int laser_from_yaml(struct yconf *yc, struct fy_node *m, const char *name,
                           struct cal_file_laser *out)
{
        static const char *const keys[] = {"d", "rms_mm", "spread_mm", "axis_angle_deg",
                                           "axis_dist_mm"};
        double *const v[] = {&out->plane.d, &out->rms_mm, &out->spread_mm, &out->axis_angle_deg,
                             &out->axis_dist_mm};
        long used = 0, given = 0;
        int r;

        snprintf(out->name, sizeof(out->name), "%s", name);
        if ((r = yconf_str(yc, m, "solved", out->solved, sizeof(out->solved))) < 0 ||
            (r = yconf_str(yc, m, "dataset", out->dataset, sizeof(out->dataset))) < 0 ||
            (r = yconf_str_req(yc, m, "camera", out->camera, sizeof(out->camera))) < 0 ||
            (r = need_vec(yc, m, "n", out->plane.n, 3)) < 0 ||
            (r = cal_yaml_numbers(yc, m, keys, v, ELEMENTSOF(keys))) < 0 ||
            (r = need_int(yc, m, "points", &out->points)) < 0 ||
            (r = need_int(yc, m, "inliers", &out->inliers)) < 0 ||
            (r = need_int(yc, m, "views_used", &used)) < 0 ||
            (r = need_int(yc, m, "views_given", &given)) < 0)
                return r;
        out->n_used = (int)used;
        out->n_views = (int)given;
        return 0;
}

/* ---- lamps.<lamp> ---- */

static void lamp_yaml(FILE *f, const void *obj)
{
        const struct cal_lamp_pos *l = obj;

        char now[32];

        cal_utc_now(now);
        fprintf(f, "solved: %s\n", now);
        cal_yaml_vec(f, "position_mm", l->pos, 3);
        fprintf(f, "rms_mm: %.4f\nobservations: %d\nnominal_dist_mm: %.3f\n", l->rms_mm, l->n_obs,
                l->nominal_dist_mm);
}

int cal_lamp_write(const char *path, const struct cal_lamp_pos *l, bool force, char *err,
                   size_t errlen)
{
        char what[DS_NAME_MAX + 16];

        snprintf(what, sizeof(what), "lamp %s", l->name);
        return cal_file_put(path,
                            &(struct cal_section){"lamps", l->name, what, "rms_mm", "mm", l->rms_mm,
                                                  "observations", "observations", l->n_obs},
                            lamp_yaml, l, force, err, errlen);
}

static int lamp_from_yaml(struct yconf *yc, struct fy_node *m, const char *name,
                          struct cal_file_lamp *out)
{
        static const char *const keys[] = {"rms_mm", "nominal_dist_mm"};
        double *const v[] = {&out->lamp.rms_mm, &out->lamp.nominal_dist_mm};
        long n = 0;
        int r;

        snprintf(out->lamp.name, sizeof(out->lamp.name), "%s", name);
        if ((r = yconf_str(yc, m, "solved", out->solved, sizeof(out->solved))) < 0 ||
            (r = need_vec(yc, m, "position_mm", out->lamp.pos, 3)) < 0 ||
            (r = cal_yaml_numbers(yc, m, keys, v, ELEMENTSOF(keys))) < 0 ||
            (r = need_int(yc, m, "observations", &n)) < 0)
                return r;
        out->lamp.n_obs = (int)n;
        return 0;
}

/* ---- the whole file ---- */

/* Reads section m named name into out (a struct of its kind). Returns 0 or -EINVAL. */
typedef int (*section_fn)(struct yconf *yc, struct fy_node *m, const char *name, void *out);

/* Reads every section of top into the array at base (elements of size, at most
 * CAL_FILE_MAX), *n of them, each with fn. */
static int read_top(struct yconf *yc, const char *top, void *base, size_t size, size_t *n,
                    section_fn fn)
{
        struct fy_node *t = yconf_get(yconf_root(yc), top);
        struct fy_node_pair *pair;
        void *iter = NULL;

        while (t && (pair = fy_node_mapping_iterate(t, &iter))) {
                struct fy_node *key = fy_node_pair_key(pair), *m = fy_node_pair_value(pair);
                const char *name = fy_node_get_scalar0(key);

                if (!name || strlen(name) >= DS_NAME_MAX)
                        return malformed(yc, key, top, "a section name must be a short string");
                if (*n >= CAL_FILE_MAX) {
                        yconf_error(yc, key, name, "more than %d %s", CAL_FILE_MAX, top);
                        return -E2BIG;
                }
                if (!m || fy_node_get_type(m) != FYNT_MAPPING)
                        return malformed(yc, m ?: key, name, "a section must be a mapping");
                if (fn(yc, m, name, (char *)base + *n * size) < 0)
                        return -EBADMSG;
                ++*n;
        }
        return 0;
}

int cal_file_read(const char *path, struct cal_file *out, char *err, size_t errlen)
{
        _cleanup_(cal_file_closep) struct yconf yc = {0};
        int r;

        memset(out, 0, sizeof(*out));
        r = cal_file_open(&yc, path, false, err, errlen);
        if (r == -ENOENT)
                snprintf(err, errlen, "%s: no such calibration file", path);
        if (r < 0 ||
            (r = read_top(&yc, "cameras", out->cameras, sizeof(out->cameras[0]), &out->n_cameras,
                          (section_fn)cal_camera_from_yaml)) < 0 ||
            (r = read_top(&yc, "turntables", out->turntables, sizeof(out->turntables[0]),
                          &out->n_turntables, (section_fn)turntable_from_yaml)) < 0 ||
            (r = read_top(&yc, "lasers", out->lasers, sizeof(out->lasers[0]), &out->n_lasers,
                          (section_fn)laser_from_yaml)) < 0)
                return r;
        return read_top(&yc, "lamps", out->lamps, sizeof(out->lamps[0]), &out->n_lamps,
                        (section_fn)lamp_from_yaml);
}

const struct cal_camera *cal_file_camera(const struct cal_file *f, const char *camera)
{
        for (size_t i = 0; i < f->n_cameras; i++)
                if (strcmp(f->cameras[i].camera, camera) == 0)
                        return &f->cameras[i];
        return NULL;
}

const struct cal_file_turntable *cal_file_turntable(const struct cal_file *f, const char *camera)
{
        for (size_t i = 0; i < f->n_turntables; i++)
                if (strcmp(f->turntables[i].camera, camera) == 0)
                        return &f->turntables[i];
        return NULL;
}

const struct cal_file_laser *cal_file_laser(const struct cal_file *f, const char *name)
{
        for (size_t i = 0; i < f->n_lasers; i++)
                if (strcmp(f->lasers[i].name, name) == 0)
                        return &f->lasers[i];
        return NULL;
}

const struct cal_lamp_pos *cal_file_lamp(const struct cal_file *f, const char *name)
{
        for (size_t i = 0; i < f->n_lamps; i++)
                if (strcmp(f->lamps[i].lamp.name, name) == 0)
                        return &f->lamps[i].lamp;
        return NULL;
}
