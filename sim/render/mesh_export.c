/* mesh_export.c - meshes handed out of the renderer (render.h): a mesh file read by the
 * scene's reader, and the scene object's placed triangles, for the appearance renderer's
 * projective texture mapping onto the true shape. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* Moves m's positions and triangles into out (m's other arrays freed). */
static void hand_out(struct mesh *m, struct sim_mesh *out)
{
        *out = (struct sim_mesh){m->nv, m->nt, m->pos, m->idx};
        m->pos = NULL;
        m->idx = NULL;
        mesh_free(m);
}

int sim_mesh_read(const char *path, struct sim_mesh *out, char *err, size_t errlen)
{
        struct mesh m = {0};
        int r = mesh_load(path, &m, err, errlen);

        if (r < 0)
                return r;
        hand_out(&m, out);
        return 0;
}

int sim_object_mesh(const struct sim_scene *s, int res, struct sim_mesh *out)
{
        const struct rgeom *g = &s->geoms[0];
        struct mesh m = {0};
        int r;

        if (!s->has_object)
                return -ENOENT;
        if (g->kind == GEOM_SPHERE) {
                if ((r = shape_sphere_mesh(g->radius, res, &m)) < 0)
                        return r;
                for (size_t i = 0; i < m.nv; i++) /* the shape sits on z = 0 about its axis */
                        for (int j = 0; j < 3; j++)
                                m.pos[3 * i + j] += g->centre[j] - (j == 2 ? g->radius : 0);
                hand_out(&m, out);
                return 0;
        }
        *out = (struct sim_mesh){g->mesh.nv, g->mesh.nt, malloc(3 * g->mesh.nv * sizeof(float)),
                                 malloc(3 * g->mesh.nt * sizeof(uint32_t))};
        if (!out->pos || !out->idx) {
                free(out->pos);
                free(out->idx);
                return -ENOMEM;
        }
        memcpy(out->pos, g->mesh.pos, 3 * g->mesh.nv * sizeof(float));
        memcpy(out->idx, g->mesh.idx, 3 * g->mesh.nt * sizeof(uint32_t));
        return 0;
}
