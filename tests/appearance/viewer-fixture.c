/* viewer-fixture.c - the model of the viewer's tests (test-viewer.py): a glossy 60 mm sphere
 * (apscene.h) seen by two cameras at 8 turntable angles (16 views, so that the views'
 * triangulation has faces and a boundary) through a lens with distortion, under 6 lamps at
 * 12 light-arm angles, fitted into
 * DIR/ds/models/default. Usage: viewer-fixture DIR. */
#include <stdio.h>

#include "appearance/model.h"
#include "tests/appearance/apscene.h"

int main(int argc, char **argv)
{
        struct aps_opts o;
        struct apscene s;
        struct ap_model *m;
        char path[4096];

        CHECK(argc == 2);
        aps_opts_default(&o, APS_GLOSSY);
        o.n_cameras = 2, o.turntable_angles = 8, o.arm_angles = 12;
        o.dist[0] = -4, o.dist[2] = 0.003,
        o.dist[3] = -0.002; /* 1-2 px at the object: the page must undo it */
        aps_open(&s, &o);
        snprintf(path, sizeof(path), "%s/ds", argv[1]);
        aps_fit_dataset(&s, path, 4, &m);
        ap_model_free(m);
        aps_close(&s);
        return 0;
}
