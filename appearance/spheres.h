/* spheres.h - a set of spheres approximating an object's mesh and the spherical signed
 * distance function (SSDF) computed from it, after Furuya et al. (seed 000 section 4.4):
 *
 *     V_d(v, zeta) = min_j  acos(unit(c_j - v) . zeta) - asin(r_j / |c_j - v|)     (eq. 9)
 *
 * over the spheres left by Algorithm 1's culling, the signed angle from the axis zeta of a
 * spherical Gaussian (SG) G(i) = exp(eta (i . zeta - 1)) to the nearest occluder boundary.
 * The visible fraction of the lobe is then a function of (V_d, eta) (eq. 12); here it is the
 * exact integral of a lobe cut by a great circle at V_d, tabulated, normalised so that an
 * unoccluded lobe (V_d = pi/2, Algorithm 1's start) is 1 (eq. 17).
 *
 * The fit (ap_spheres_fit) is medial-axis style: the centres of a grid's cells inside the mesh
 * (parity of vertical rays) with their distance to the surface (sampled densely); the deepest
 * cell is the first sphere, its depth the radius, then the deepest cell outside every sphere
 * so far, and so on: inscribed spheres centred on the medial axis, largest first, until n or
 * the object is filled. docs/appearance.md, "Environment relighting". */
#pragma once

#include "appearance/raster.h"

#define AP_SPHERES_MAX   1024
#define AP_SG_VIS_ETAS   40 /* table of the visible fraction: sharpness 0.5 .. 2e4, log steps */
#define AP_SG_VIS_ANGLES 65 /* signed angle -pi/2 .. pi/2 */

struct ap_spheres {
        int n;
        float *s;   /* 4 per sphere: centre x, y, z (object frame, mm), radius */
        float cell; /* the fit's grid step: spheres touching a point closer than this are its own */
        float vis[AP_SG_VIS_ETAS * AP_SG_VIS_ANGLES]; /* ap_sg_visible's table */
};

/* Fits n (1..AP_SPHERES_MAX) spheres to the closed mesh m into *out (free with
 * ap_spheres_free); grid: cells along the longest side (8..128). Returns 0, -EINVAL (bad n,
 * an empty mesh, no cell inside it: not closed) or -ENOMEM. Fewer than n spheres when the
 * mesh holds fewer cells. */
int ap_spheres_fit(const struct ap_mesh *m, int n, int grid, struct ap_spheres *out);

/* Fills s->vis (done by ap_spheres_fit; for sets built by hand). */
void ap_spheres_table(struct ap_spheres *s);

/* Frees s's arrays and zeroes it. Safe on a zeroed set. */
void ap_spheres_free(struct ap_spheres *s);

/* Algorithm 1: the SSDF at surface point v (normal n) towards unit zeta, at most pi/2 (no
 * occluder); spheres behind the tangent plane or touching v (within s->cell) are culled. */
float ap_ssdf(const struct ap_spheres *s, const float v[3], const float n[3], const float zeta[3]);

/* The visible fraction (0..1) of an SG of sharpness eta whose axis is at SSDF theta_d. */
float ap_sg_visible(const struct ap_spheres *s, float theta_d, float eta);
