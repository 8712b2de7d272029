/* views.h - the triangulated sphere of sampled view directions (seed 001 section 4.2):
 * the convex hull of the unit view directions, whose faces are the spherical Delaunay
 * triangles of the views, and the barycentric weights of the up-to-3 views around any
 * direction (the neighbouring-view functions I(v; n) and H(v; n) of the paper).
 *
 * Views usually cover part of the sphere only (cameras on an upper arc). Hull faces that
 * span a region with no views (a cap of a hemisphere or more, or a face far larger than
 * the others: more than AP_VIEWS_HOLE_RATIO times the median face's circumradius) are
 * holes; a direction that falls in a hole, or when every view lies on one plane (a single
 * ring of turntable angles), is interpolated on the nearest boundary edge (two views, by
 * the position of its projection on the arc) or takes its nearest view alone.
 * docs/appearance.md, "Rendering". */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#define AP_VIEWS_HOLE_RATIO 2.0 /* a face this many times the median circumradius is a hole */
#define AP_VIEWS_CUBE       16  /* texels per cube-map face side of the start-face table */
#define AP_VIEWS_OUTSIDE    -2  /* ap_views_start: the texel lies outside the covered region */

struct ap_views;

/* Triangulates the n unit directions dirs (object frame). Directions closer than 1e-6 rad to
 * an earlier one are never chosen (their earlier twin is). Returns 0, -EINVAL (n == 0, a
 * zero vector) or -ENOMEM. Costs O(n^4) in the worst case: about 10 ms for 100 views. */
int ap_views_new(const double (*dirs)[3], size_t n, struct ap_views **ret);

/* Frees v; NULL is a no-op. Returns NULL. */
struct ap_views *ap_views_free(struct ap_views *v);

/* The views interpolated at unit direction d: their indices in idx and their weights in w
 * (non-negative, summing to 1); slots past the returned count hold idx[0] and weight 0.
 * Returns 1, 2 or 3. Thread-safe, no allocation: cheap enough to call per pixel. */
int ap_views_weights(const struct ap_views *v, const float d[3], int idx[3], float w[3]);

/* Angle in radians between d and the region the views cover (0 inside a non-hole face). */
double ap_views_outside_angle(const struct ap_views *v, const double d[3]);

/* Number of faces that are not holes (0 when the views are coplanar or fewer than 3). */
size_t ap_views_n_faces(const struct ap_views *v);

/* The triangulation as data, for a renderer elsewhere (the web viewer, webexport.h). Face i
 * (i < ap_views_n_faces, holes left out): its views in idx, its edge vectors e (d . e[j] is
 * the unnormalised weight of idx[j] at direction d: d is in the face when they sum > 0 and
 * each is >= -1e-6 of the sum), and in nb[j] the face across the edge opposite idx[j] (-1:
 * none, or a hole). */
void ap_views_face(const struct ap_views *v, size_t i, int idx[3], float e[3][3], int nb[3]);

/* The start face of a walk to the face around a direction (cube.h addressing, texel
 * (face * AP_VIEWS_CUBE + t) * AP_VIEWS_CUBE + s of 6 AP_VIEWS_CUBE^2): a face index as
 * ap_views_face's, -1 (search every face) or AP_VIEWS_OUTSIDE. */
int ap_views_start(const struct ap_views *v, size_t texel);

/* Number of boundary edges (views.h's top comment: where directions outside are taken). */
size_t ap_views_n_boundary(const struct ap_views *v);

/* Boundary edge i (i < ap_views_n_boundary): its two views and the unit a x b. */
void ap_views_boundary(const struct ap_views *v, size_t i, int ab[2], double n[3]);

/* Whether view i repeats an earlier view's direction (then it is never chosen). */
bool ap_views_is_dup(const struct ap_views *v, size_t i);
