/* calfile.h - the calibration file (calibration.yaml, docs/calibration.md): one YAML
 * document, `format: gonio-calibration 1`, with one section per calibrated thing under a
 * top-level mapping per kind (cameras.<camera>, turntables.<camera>, lasers.<laser>,
 * lamps.<lamp>). A section is replaced as a whole, every other section kept as it is; the
 * file is written atomically (common/fileio) and a section is never replaced by a worse
 * result (CAL_WORSE on its RMS) unless forced. cal_file_read() reads every section at once
 * for the consumers (scan reconstruction, appearance model). */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#include "calib/camera.h"
#include "calib/laserplane.h"
#include "common/yconf.h"

#define CAL_FILE_FORMAT "gonio-calibration 1"
#define CAL_FILE_MAX    16 /* sections of each kind cal_file_read keeps */

/* One section to put into a calibration file, and what the never-worse rule compares. */
struct cal_section {
        const char *top;        /* "cameras" */
        const char *name;       /* "c0" */
        const char *what;       /* "camera c0", for messages */
        const char *rms_key;    /* "rms_px": the old section's figure, compared with rms */
        const char *unit;       /* "px" */
        double rms;             /* the new result's */
        const char *count_key;  /* "views_used": how much the figures rest on, for messages */
        const char *count_what; /* "views" */
        long count;             /* the new result's */
};

/* Writes one section's YAML (a block mapping, one key per line) for obj into f. */
typedef void (*cal_emit_fn)(FILE *f, const void *obj);

/* Replaces (or adds) section s->top.s->name of the calibration file at path (created when
 * missing) with what emit writes for obj, keeping every other section, atomically. When the
 * file's section has a better result (CAL_WORSE(s->rms, its s->rms_key)), it is kept and
 * -EEXIST returned with both results in err, unless force. Returns 0, -EEXIST, -EBADMSG (the
 * file is not a calibration file: err says where), -ENOMEM or the -errno of the write. */
int cal_file_put(const char *path, const struct cal_section *s, cal_emit_fn emit, const void *obj,
                 bool force, char *err, size_t errlen);

/* Opens the calibration file at path into yc and checks its format line and that each
 * top-level section is a mapping. With create, a missing file gives an empty document.
 * Returns 0, -ENOENT (no file, !create), -EBADMSG (err says where) or -errno. */
int cal_file_open(struct yconf *yc, const char *path, bool create, char *err, size_t errlen);

/* For _cleanup_(cal_file_closep) on a struct yconf opened by cal_file_open. */
static inline void cal_file_closep(struct yconf *yc)
{
        yconf_close(yc);
}

/* Writes `key: "s"\n` to f, s quoted and escaped as a YAML double-quoted scalar. */
void cal_yaml_str(FILE *f, const char *key, const char *s);

/* Writes `key: [v0, v1, ...]\n` to f (n numbers, %.10g). */
void cal_yaml_vec(FILE *f, const char *key, const double *v, size_t n);

/* Writes `board: { ... }\n` for b to f; cal_yaml_read_board reads it back from mapping m.
 * Returns 0 or -EINVAL (yc->err says where). */
void cal_yaml_board(FILE *f, const struct cal_board *b);
int cal_yaml_read_board(struct yconf *yc, struct fy_node *m, struct cal_board *b);

/* Reads the numbers keys[i] of mapping m into v[i] (n of them), each required. Returns 0 or
 * -EINVAL (yc->err says which and where). */
int cal_yaml_numbers(struct yconf *yc, struct fy_node *m, const char *const *keys, double *const *v,
                     size_t n);

/* The current UTC time as ISO 8601 ("2026-11-30T01:02:03Z") into out. */
void cal_utc_now(char out[32]);

/* Reads the camera section m (named name) of an open calibration file into out (views not
 * read: NULL). For cal_camera_read and cal_file_read. Returns 0 or -EINVAL (yc->err). */
int cal_camera_from_yaml(struct yconf *yc, struct fy_node *m, const char *name,
                         struct cal_camera *out);

/* ---- turntables.<camera> ---- */

/* The turntable's axis and a camera's pose, as the file keeps them. */
struct cal_file_turntable {
        char camera[DS_NAME_MAX];
        char solved[32];   /* UTC; "" when writing: now */
        char dataset[256]; /* where the views came from */
        struct cal_board board;
        struct cal_turntable tt; /* R, t, axis, origin, figures and view counts */
};

/* Writes t as turntables.<t->camera> of the file at path, never over a section with a
 * better rms_px unless force. Returns as cal_file_put. */
int cal_turntable_write(const char *path, const struct cal_file_turntable *t, bool force, char *err,
                        size_t errlen);

/* ---- lasers.<laser> ---- */

/* A laser's plane in the turntable frame (x_cam = R x_tt + t of its camera's turntable
 * section), as the file keeps it. */
struct cal_file_laser {
        char name[DS_NAME_MAX];
        char camera[DS_NAME_MAX]; /* the camera it was seen by */
        char solved[32], dataset[256];
        struct cal_plane plane; /* turntable frame, mm */
        double rms_mm, spread_mm;
        long points, inliers;
        int n_views, n_used;
        double axis_angle_deg, axis_dist_mm; /* the plane against the turntable axis */
};

/* Writes laser name, solved by camera as l (camera frame) from dataset, as lasers.<name> of
 * the file at path: its plane moved into the turntable frame of the file's section
 * turntables.<camera> (cal_plane_to_turntable) with its angle and distance from the axis.
 * Never over a section with a better rms_mm unless force. Returns as cal_file_put, or
 * -ENOENT when the file has no turntable section of camera (err: calibrate the turntable
 * first). */
int cal_laser_write(const char *path, const char *name, const char *camera,
                    const struct cal_laser *l, const char *dataset, bool force, char *err,
                    size_t errlen);

/* ---- lamps.<lamp> ---- */

/* A lamp's position, as the lamp solver gives it. */
struct cal_lamp_pos {
        char name[DS_NAME_MAX];
        double pos[3]; /* mm, turntable frame at angle 0 */
        double rms_mm;
        int n_obs;
        double nominal_dist_mm; /* distance from the rig file's nominal position */
};

/* Writes l as lamps.<l->name> of the file at path (solved: now), never over a section with
 * a better rms_mm unless force. Returns as cal_file_put. */
int cal_lamp_write(const char *path, const struct cal_lamp_pos *l, bool force, char *err,
                   size_t errlen);

/* ---- the whole file ---- */

struct cal_file_lamp {
        struct cal_lamp_pos lamp;
        char solved[32];
};

/* Every section of a calibration file. */
struct cal_file {
        size_t n_cameras, n_turntables, n_lasers, n_lamps;
        struct cal_camera cameras[CAL_FILE_MAX]; /* views NULL */
        struct cal_file_turntable turntables[CAL_FILE_MAX];
        struct cal_file_laser lasers[CAL_FILE_MAX];
        struct cal_file_lamp lamps[CAL_FILE_MAX];
};

/* Reads every section of the calibration file at path into out (zeroed first; sections of
 * kinds it does not know are skipped). Returns 0, -ENOENT (no file), -EBADMSG (malformed:
 * err says file, line and key), -E2BIG (more than CAL_FILE_MAX sections of a kind) or
 * -errno. */
int cal_file_read(const char *path, struct cal_file *out, char *err, size_t errlen);

/* Lookups by name in a read file; NULL when absent. Valid as long as f. */
const struct cal_camera *cal_file_camera(const struct cal_file *f, const char *camera);
const struct cal_file_turntable *cal_file_turntable(const struct cal_file *f, const char *camera);
const struct cal_file_laser *cal_file_laser(const struct cal_file *f, const char *name);
const struct cal_lamp_pos *cal_file_lamp(const struct cal_file *f, const char *name);
