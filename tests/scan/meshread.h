/* meshread.h - what the scan tests check of a mesh: its faces' consistency, and its PLY and
 * OBJ files read back by small readers written from the formats' descriptions (PLY: Greg
 * Turk's format as in paulbourke.net/dataformats/ply; OBJ: Wavefront's Appendix B1), not
 * from the writers. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "calib/mesh.h"

/* The unit normal n (by the right-hand rule of the face's order) and the centre c of face f
 * (3 indices into v). */
void mr_face_normal(const struct sec_point *v, const uint32_t *f, double n[3], double c[3]);

/* Checks that no directed edge occurs twice in the n faces f (each edge of an orientable
 * surface is walked once each way, or once on the border) and returns the number of border
 * edges (walked once). Exits the test on failure. */
size_t mr_check_edges(const uint32_t *f, size_t n);

/* The keys (line << 32 | row, unique in a scan) of the vertices of m on its border (edges of
 * one face), sorted, into *keys (freed by the caller). Returns their number. */
size_t mr_border_vertices(const struct cal_mesh *m, uint64_t **keys);

/* Whether m has the vertex of key (mr_border_vertices). */
bool mr_has_vertex(const struct cal_mesh *m, uint64_t key);

/* Reads the PLY file dir_fd/name (binary little-endian; a vertex element of x y z nx ny nz
 * red green blue in any order and types, an optional face element of vertex_indices lists)
 * into *out (free with cal_mesh_free). Exits the test on anything else. */
void mr_read_ply(int dir_fd, const char *name, struct cal_mesh *out);

/* Reads the PLY file dir_fd/name (mr_read_ply) and checks it holds m: positions, normals,
 * colours, faces. */
void mr_expect_ply(int dir_fd, const char *name, const struct cal_mesh *m);

/* Reads the OBJ file dir_fd/name (v with optional colour, vn, f with v, v/vt, v//vn, v/vt/vn
 * and negative indices) and checks it holds m. */
void mr_expect_obj(int dir_fd, const char *name, const struct cal_mesh *m);
