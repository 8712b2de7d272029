/* export.h - a dataset and its appearance model written in formats that other tools read
 * (docs/exports.md): COLMAP's text model, nerfstudio's transforms.json, PLY, and RTI (.lp
 * light files, the relight web format, PTM). Every export is written into a temporary folder
 * beside the destination and renamed into place, so that nothing is ever half written. */
#pragma once

#include <stddef.h>

struct ds;
struct rig_backend;

struct ap_export_opts {
        const char *model;       /* models/<name> of the dataset to export from; NULL: "default" */
        const char *calibration; /* calibration file, "nominal", or NULL: the dataset's own */
        const struct rig_backend *const *backends; /* to read the dataset's rig.yaml */
        char *notes;      /* NULL, or notes_len bytes for what the export did besides writing: */
        size_t notes_len; /* temporary folders of killed exports removed ("" for nothing) */
};

/* Writes the dataset at ds_dir as format ("colmap", "nerfstudio", "ply", "rti", "gltf") into
 * the folder out_dir, which must not exist or be empty: built in a temporary folder, locked
 * while it is written, then renamed; out_dir's temporary folders that no live export holds
 * (left by a killed one) are removed first and counted in o->notes. Returns 0, -EINVAL
 * (unknown format, with the known ones in err), -EEXIST (out_dir not empty), -ENOENT (what
 * the format needs is missing: a model, a scan) or -errno, with a sentence in err. */
int ap_export(const char *ds_dir, const char *format, const char *out_dir,
              const struct ap_export_opts *o, char *err, size_t errlen);

/* Fills a folder: writes into the empty folder dir, or returns -errno with a sentence in err. */
typedef int (*ap_fill_fn)(void *ctx, const char *dir, char *err, size_t errlen);

/* Creates the folder out_dir (which must not exist or be empty) by fill(ctx, ...) on a
 * temporary folder beside it, locked while filled, renamed into place when fill succeeds and
 * removed when not; out_dir's temporary folders no live writer holds are removed first.
 * Returns 0, -EEXIST (out_dir not empty), or fill's or the file system's -errno, with a
 * sentence in err. */
int ap_write_folder(const char *out_dir, ap_fill_fn fill, void *ctx, char *err, size_t errlen);

/* The writers ap_export dispatches to: each fills the empty folder dir from the dataset d
 * (ds_dir its directory), or returns -errno with a sentence in err. */
int ap_export_colmap(struct ds *d, const char *ds_dir, const char *dir,
                     const struct ap_export_opts *o, char *err, size_t errlen);
int ap_export_nerfstudio(struct ds *d, const char *ds_dir, const char *dir,
                         const struct ap_export_opts *o, char *err, size_t errlen);
int ap_export_ply(struct ds *d, const char *ds_dir, const char *dir, const struct ap_export_opts *o,
                  char *err, size_t errlen);
int ap_export_rti(struct ds *d, const char *ds_dir, const char *dir, const struct ap_export_opts *o,
                  char *err, size_t errlen);
/* glTF 2.0 of the BRDF model models/<o->model> (default "default"); -ENOENT without one. */
int ap_export_gltf(struct ds *d, const char *ds_dir, const char *dir,
                   const struct ap_export_opts *o, char *err, size_t errlen);

struct ap_brdf_model;

/* Writes the BRDF model m (brdf.h) as glTF 2.0 into the folder dir, which must not exist or be
 * empty (as ap_write_folder): model.gltf, model.bin and its PNG textures (docs/exports.md,
 * "glTF"). Returns 0, -EINVAL (no model, an empty mesh), -EEXIST or -errno, with a sentence
 * in err. */
int ap_export_gltf_model(const struct ap_brdf_model *m, const char *dir, char *err, size_t errlen);
