/* mesh.h - a triangle mesh from a light-sectioning cloud (calib/section.h): the points of
 * each laser joined over the (angle, row) grid, consecutive lines and neighbouring rows,
 * a quad only where its four corners exist and no edge is longer than its expected length
 * times a factor, so holes, occlusions and silhouettes stay open; wound so that every
 * face looks at the camera (outward); closed across the 360-degree seam when the lines
 * cover the full turn. Then simplified to a target triangle count with meshoptimizer
 * (borders kept, an error limit in mm), with vertex normals from the faces.
 * docs/scanning.md, "The mesh". */
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "calib/section.h"

/* A triangle mesh: vertices (sec_point: position, normal, colour) and 3 indices a face. */
struct cal_mesh {
        struct sec_point *v;
        size_t n_v;
        uint32_t *tri; /* 3 * n_tri indices into v, counter-clockwise seen from outside */
        size_t n_tri;
        int seams_closed; /* lasers whose grid was closed across 360 degrees */
        size_t folds;     /* faces cal_mesh_simplify dropped as folds */
};

/* How the grid is joined (cal_mesh_opts_default). */
struct cal_mesh_opts {
        double max_edge;  /* an edge longer than this many times its expected length is a gap */
        double seam_step; /* the seam closes when the step from the last line round to the
                           * first is at most this many times the median step */
};

/* The defaults (docs/scanning.md): max_edge 5, seam_step 1.5. Never fails. */
void cal_mesh_opts_default(struct cal_mesh_opts *o);

/* Joins c's points into *out (zeroed first; the vertices are a copy of c's points, those in
 * no face dropped) with vertex normals from the faces. Lines of one laser must be in angle
 * order (as for sec_normals). Returns 0, -EINVAL (o out of range) or -ENOMEM. Free with
 * cal_mesh_free. */
int cal_mesh_from_grid(const struct sec_ctx *c, const struct cal_mesh_opts *o,
                       struct cal_mesh *out);

/* Simplifies m in place to at most target triangles (meshopt_simplify), no vertex of the
 * border moving and no face farther than max_error_mm from the original surface; the error
 * limit wins, so the count can stay above target (then *error_mm is near the limit). Then
 * drops the faces turned more than 75 degrees from their corners' normals (folds of
 * slivers, counted in m->folds) and unused vertices, and recomputes the normals. *error_mm (may be
 * NULL) gets the deviation meshoptimizer reports, in mm. Returns 0, -EINVAL (target 0 or
 * max_error_mm not positive) or -ENOMEM; m unchanged on failure. */
int cal_mesh_simplify(struct cal_mesh *m, size_t target, double max_error_mm, double *error_mm);

/* Frees m's arrays and zeroes it. Safe on a zeroed mesh. */
void cal_mesh_free(struct cal_mesh *m);
