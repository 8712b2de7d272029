/* fuzz-mesh.c - libFuzzer target of the PLY and OBJ mesh reader (sim/render/meshio.c, through
 * sim_mesh_read: the scene's "mesh" shape and appearance/mesh.c's scanned mesh): the input is
 * a mesh file, read as .ply when it starts with "ply" (as every PLY file does), else as .obj.
 * Every index of a mesh read must name one of its vertices. */
#include <stdlib.h>
#include <string.h>

#include "fuzz.h"
#include "sim/render/render.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
        bool ply = size >= 3 && memcmp(data, "ply", 3) == 0;
        const char *path = fuzz_file(data, size, ply ? ".ply" : ".obj");
        struct sim_mesh m = {0};
        char err[512];

        if (sim_mesh_read(path, &m, err, sizeof(err)) == 0)
                for (size_t i = 0; i < 3 * m.nt; i++)
                        if (m.idx[i] >= m.nv)
                                abort();
        free(m.pos);
        free(m.idx);
        return 0;
}
