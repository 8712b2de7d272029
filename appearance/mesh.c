/* mesh.c - the object's mesh of a dataset (mesh.h): mesh.ply of the scan through the
 * simulator's mesh reader (one PLY reader in the project), else the scene object of the
 * dataset's simulated rig. */
#include <errno.h>
#include <meshoptimizer.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "appearance/mesh.h"
#include "calib/scan.h"
#include "common/cleanup.h"
#include "sim/render/render.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_scene *, sim_scene_free);

/* Takes m's arrays into out, oriented (ap_mesh_orient). */
static int take(struct sim_mesh *m, struct ap_mesh *out)
{
        *out = (struct ap_mesh){m->nv, m->nt, m->pos, m->idx, 0};
        return ap_mesh_orient(out);
}

static int from_rig(const char *rig, const struct rig_backend *const *backends, struct ap_mesh *out,
                    char *err, size_t errlen)
{
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        _cleanup_(sim_scene_freep) struct sim_scene *s = NULL;
        struct sim_mesh m;
        int r;

        if ((r = rigconf_load_stored(rig, backends, &rc, err, errlen)) < 0 ||
            (r = sim_scene_new(rc, &s, err, errlen)) < 0)
                return r;
        if ((r = sim_object_mesh(s, AP_MESH_SPHERE_ROWS, &m)) < 0) {
                snprintf(err, errlen, "%s: the scene has no object to render on", rig);
                return r;
        }
        return take(&m, out);
}

int ap_mesh_for_dataset(const char *ds_dir, const struct rig_backend *const *backends,
                        struct ap_mesh *out, char *src, size_t srclen, char *err, size_t errlen)
{
        char path[4096];
        struct sim_mesh m;
        int r;

        *out = (struct ap_mesh){0};
        snprintf(path, sizeof(path), "%s/%s", ds_dir, SCAN_FILE_MESH_PLY);
        if (access(path, F_OK) == 0) {
                if ((r = sim_mesh_read(path, &m, err, errlen)) < 0)
                        return r;
                snprintf(src, srclen, "scan %s", path);
                return take(&m, out);
        }
        snprintf(path, sizeof(path), "%s/rig.yaml", ds_dir);
        if (access(path, F_OK) != 0) {
                snprintf(err, errlen, "%s: no %s and no rig.yaml: no shape to render on", ds_dir,
                         SCAN_FILE_MESH_PLY);
                return -ENOENT;
        }
        if ((r = from_rig(path, backends, out, err, errlen)) < 0)
                return r;
        snprintf(src, srclen, "simulator %s", path);
        return 0;
}

int ap_mesh_simplify(struct ap_mesh *m, size_t target)
{
        uint32_t *idx;
        float *pos, err;
        size_t n;

        if (!target)
                return -EINVAL;
        if (m->nt <= target)
                return 0;
        if (m->front < 0) /* wound counter-clockwise from outside, so that winding says out */
                for (size_t t = 0; t < m->nt; t++) {
                        uint32_t v = m->idx[3 * t + 1];
                        m->idx[3 * t + 1] = m->idx[3 * t + 2];
                        m->idx[3 * t + 2] = v;
                }
        idx = malloc(3 * m->nt * sizeof(*idx));
        pos = malloc(3 * m->nv * sizeof(*pos));
        if (!idx || !pos) {
                free(idx);
                free(pos);
                return -ENOMEM;
        }
        n = meshopt_simplify(idx, m->idx, 3 * m->nt, m->pos, m->nv, 3 * sizeof(float), 3 * target,
                             1.f, 0, &err);
        if (n > 6 * target) /* collapses stopped at the mesh's features: drop them too */
                n = meshopt_simplifySloppy(idx, idx, n, m->pos, m->nv, 3 * sizeof(float),
                                           3 * target, 1.f, &err);
        m->nv = meshopt_optimizeVertexFetch(pos, idx, n, m->pos, m->nv, 3 * sizeof(float));
        free(m->idx);
        free(m->pos);
        m->idx = idx;
        m->pos = pos;
        m->nt = n / 3;
        return ap_mesh_orient(m);
}
