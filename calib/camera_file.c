/* camera_file.c - the calibration file (calibration.yaml, docs/calibration.md): one section
 * per camera under "cameras", other sections kept as they are; written atomically, never
 * replacing a better camera section by a worse one unless forced (camera.h). */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/camera.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/yconf.h"

#define CAL_FILE_FORMAT "gonio-calibration 1"

static void yconf_closep(struct yconf *yc)
{
        yconf_close(yc);
}

/* s as a double-quoted YAML scalar (our texts hold no control characters). */
static void quoted(FILE *f, const char *s)
{
        fputc('"', f);
        for (; *s; s++) {
                if (*s == '"' || *s == '\\')
                        fputc('\\', f);
                fputc(*s, f);
        }
        fputc('"', f);
}

static void board_yaml(FILE *f, const struct cal_board *b)
{
        fprintf(f, "board: { type: %s, squares: [%d, %d], square_mm: %.9g",
                b->type == CAL_BOARD_CHARUCO ? "charuco" : "chessboard", b->squares_x, b->squares_y,
                b->square_mm);
        if (b->type == CAL_BOARD_CHARUCO)
                fprintf(f, ", marker_mm: %.9g", b->marker_mm);
        fprintf(f, " }\n");
}

/* The camera's section as YAML text (malloc'd). */
static char *section_yaml(const struct cal_camera *c)
{
        char *text = NULL;
        size_t len = 0;
        FILE *f = open_memstream(&text, &len);

        if (!f)
                return NULL;
        fprintf(f, "solved: %s\ndataset: ", c->solved);
        quoted(f, c->dataset);
        fprintf(f, "\n");
        board_yaml(f, &c->board);
        fprintf(f, "width: %d\nheight: %d\n", c->width, c->height);
        fprintf(f, "fx: %.10g\nfy: %.10g\ncx: %.10g\ncy: %.10g\n", c->k.fx, c->k.fy, c->k.cx,
                c->k.cy);
        fprintf(f, "dist: [%.9g, %.9g, %.9g, %.9g, %.9g]\n", c->k.dist[0], c->k.dist[1],
                c->k.dist[2], c->k.dist[3], c->k.dist[4]);
        fprintf(f, "std_px: [%.4g, %.4g, %.4g, %.4g]\n", c->std[0], c->std[1], c->std[2],
                c->std[3]);
        fprintf(f, "rms_px: %.4f\nviews_used: %zu\nviews_rejected: %zu\n", c->rms, c->n_used,
                c->n_views - c->n_used);
        if (c->n_used < c->n_views)
                fprintf(f, "rejected:\n");
        for (size_t i = 0; i < c->n_views; i++) {
                if (c->views[i].used)
                        continue;
                fprintf(f, "  - { file: ");
                quoted(f, c->views[i].file);
                fprintf(f, ", reason: ");
                quoted(f, c->views[i].reason);
                fprintf(f, " }\n");
        }
        if (fclose(f) != 0) {
                free(text);
                return NULL;
        }
        return text;
}

/* The existing file, or a new document when there is none. */
static int open_doc(const char *path, struct yconf *yc, char *err, size_t errlen)
{
        int r = yconf_open(yc, path, err, errlen);

        if (r == -ENOENT)
                r = yconf_open_string(yc, path, "format: " CAL_FILE_FORMAT "\ncameras: {}\n", err,
                                      errlen);
        if (r < 0)
                return r == -EINVAL ? -EBADMSG : r;
        if (!yconf_get(yconf_root(yc), "cameras") ||
            fy_node_get_type(yconf_get(yconf_root(yc), "cameras")) != FYNT_MAPPING) {
                snprintf(err, errlen, "%s: not a calibration file (no 'cameras' mapping)", path);
                return -EBADMSG;
        }
        return 0;
}

/* -EEXIST when the file's section for c's camera is better than c. */
static int keep_better(struct yconf *yc, struct fy_node *old, const struct cal_camera *c,
                       const char *path)
{
        double rms = -1;
        long used = 0;

        if (yconf_double(yc, old, "rms_px", 0, 1e6, &rms) <= 0 ||
            yconf_int(yc, old, "views_used", 0, 1L << 30, &used) < 0 || !CAL_WORSE(c->rms, rms))
                return 0;
        snprintf(yc->err, yc->errlen,
                 "kept the calibration of camera %s in %s (RMS %.3f px from %ld views): the new "
                 "one is worse (RMS %.3f px from %zu views); force to replace it",
                 c->camera, path, rms, used, c->rms, c->n_used);
        return -EEXIST;
}

static int put_section(struct yconf *yc, const struct cal_camera *c)
{
        struct fy_node *cams = yconf_get(yconf_root(yc), "cameras");
        struct fy_node_pair *pair = fy_node_mapping_lookup_pair_by_string(cams, c->camera, -1);
        char *text = section_yaml(c);
        /* the document keeps pointers into its source text: hand it text to own */
        struct fy_node *node = text ? fy_node_build_from_malloc_string(yc->doc, text, FY_NT) : NULL;

        if (!node) /* text is not freed: whether libfyaml took it on failure is unsaid */
                return -ENOMEM;
        if (pair)
                return fy_node_pair_set_value(pair, node) < 0 ? -ENOMEM : 0;
        struct fy_node *key = fy_node_create_scalar_copy(yc->doc, c->camera, FY_NT);
        if (!key || fy_node_mapping_append(cams, key, node) < 0)
                return -ENOMEM;
        return 0;
}

int cal_camera_write(const char *path, const struct cal_camera *c, bool force, char *err,
                     size_t errlen)
{
        _cleanup_(yconf_closep) struct yconf yc = {0};
        _cleanup_free_ char *out = NULL;
        struct fy_node *old;
        int r;

        r = open_doc(path, &yc, err, errlen);
        if (r < 0)
                return r;
        old = yconf_get(yconf_get(yconf_root(&yc), "cameras"), c->camera);
        if (old && !force && (r = keep_better(&yc, old, c, path)) < 0)
                return r;
        r = put_section(&yc, c);
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

static int read_board(struct yconf *yc, struct fy_node *m, struct cal_board *b)
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
        b->type = !strcmp(type, "charuco") ? CAL_BOARD_CHARUCO : CAL_BOARD_CHESSBOARD;
        b->squares_x = (int)sq[0];
        b->squares_y = (int)sq[1];
        return 0;
}

static int read_numbers(struct yconf *yc, struct fy_node *m, struct cal_camera *out)
{
        struct {
                const char *key;
                double *v;
        } const keys[] = {{"fx", &out->k.fx},
                          {"fy", &out->k.fy},
                          {"cx", &out->k.cx},
                          {"cy", &out->k.cy},
                          {"rms_px", &out->rms}};
        long w = 0, h = 0, used = 0, rejected = 0;
        int r;

        for (size_t i = 0; i < ELEMENTSOF(keys); i++)
                if ((r = yconf_double(yc, m, keys[i].key, -1e9, 1e9, keys[i].v)) <= 0)
                        return r < 0 ? r : yconf_error(yc, m, keys[i].key, "missing");
        if ((r = yconf_doubles(yc, m, "dist", out->k.dist, 5, 5, NULL)) < 0 ||
            (r = yconf_doubles(yc, m, "std_px", out->std, 4, 4, NULL)) < 0 ||
            (r = yconf_int(yc, m, "width", 0, 1 << 20, &w)) < 0 ||
            (r = yconf_int(yc, m, "height", 0, 1 << 20, &h)) < 0 ||
            (r = yconf_int(yc, m, "views_used", 0, 1L << 30, &used)) < 0 ||
            (r = yconf_int(yc, m, "views_rejected", 0, 1L << 30, &rejected)) < 0)
                return r;
        out->width = (int)w;
        out->height = (int)h;
        out->n_used = (size_t)used;
        out->n_views = (size_t)(used + rejected);
        return 0;
}

int cal_camera_read(const char *path, const char *name, struct cal_camera *out, char *err,
                    size_t errlen)
{
        _cleanup_(yconf_closep) struct yconf yc = {0};
        struct fy_node *m;
        int r;

        memset(out, 0, sizeof(*out));
        r = yconf_open(&yc, path, err, errlen);
        if (r < 0)
                return r == -EINVAL ? -EBADMSG : r;
        m = yconf_get(yconf_get(yconf_root(&yc), "cameras"), name);
        if (!m) {
                snprintf(err, errlen, "%s: no calibration of camera %s", path, name);
                return -ENOENT;
        }
        snprintf(out->camera, sizeof(out->camera), "%s", name);
        if ((r = yconf_str(&yc, m, "solved", out->solved, sizeof(out->solved))) < 0 ||
            (r = yconf_str(&yc, m, "dataset", out->dataset, sizeof(out->dataset))) < 0 ||
            (r = read_board(&yc, m, &out->board)) < 0 || (r = read_numbers(&yc, m, out)) < 0)
                return -EBADMSG;
        return 0;
}
