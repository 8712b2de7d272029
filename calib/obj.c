/* obj.c - the mesh as a Wavefront OBJ text file (see obj.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "obj.h"

/* Prints m as OBJ to f. */
static void print_obj(FILE *f, const struct cal_mesh *m)
{
        fprintf(f, "# gonio scan mesh, object frame, mm: %zu vertices, %zu triangles\n", m->n_v,
                m->n_tri);
        for (size_t i = 0; i < m->n_v; i++) {
                const struct sec_point *p = &m->v[i];
                fprintf(f, "v %.9g %.9g %.9g %.4f %.4f %.4f\n", p->x[0], p->x[1], p->x[2],
                        p->rgb[0] / 255.0, p->rgb[1] / 255.0, p->rgb[2] / 255.0);
        }
        for (size_t i = 0; i < m->n_v; i++)
                fprintf(f, "vn %.6f %.6f %.6f\n", m->v[i].n[0], m->v[i].n[1], m->v[i].n[2]);
        for (size_t t = 0; t < m->n_tri; t++) {
                const uint32_t *v = m->tri + 3 * t;
                fprintf(f, "f %u//%u %u//%u %u//%u\n", v[0] + 1, v[0] + 1, v[1] + 1, v[1] + 1,
                        v[2] + 1, v[2] + 1);
        }
}

int obj_write_mesh(int dir_fd, const char *name, const struct cal_mesh *m)
{
        _cleanup_free_ char *buf = NULL;
        size_t len = 0;
        FILE *f = open_memstream(&buf, &len);
        int r;

        if (!f)
                return -ENOMEM;
        print_obj(f, m);
        r = ferror(f);
        if (fclose(f) != 0 || r)
                return -ENOMEM;
        return gn_write_atomic(dir_fd, name, buf, len, NULL);
}
