/* meshdist.h - the exact distance from a point to a triangle mesh (the renderer's true object,
 * sim_object_mesh), through a uniform grid of the triangles: how the scans of faceted and
 * relief objects are scored, every point, against the surface the renderer traced. */
#pragma once
#include <stddef.h>
#include <stdint.h>

#include "sim/render/render.h"

struct meshdist {
        struct sim_mesh m;
        double lo[3], cell; /* the grid's corner (mm) and cell size */
        int dim[3];         /* cells along x, y, z */
        uint32_t *start;    /* cell c's triangles: tri[start[c] .. start[c + 1]) */
        uint32_t *tri;
};

/* Takes the mesh m (owned from now on) and bins its triangles into cells of about cell mm. */
void md_open(struct meshdist *md, struct sim_mesh m, double cell);
void md_close(struct meshdist *md);

/* The point c of the mesh closest to p and the outward unit normal there n (the triangle's,
 * by its winding); returns the distance, INFINITY for an empty mesh. */
double md_closest(const struct meshdist *md, const double p[3], double c[3], double n[3]);
