/* lampscene.c - the mirror-sphere scene of the lamps' tests (lampscene.h). */
#include <fcntl.h>
#include <math.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/riggeom.h"
#include "tests/calib/lampscene.h"
#include "tests/dataset/ds-util.h"

static const char lamps_fmt[] =
        "lamps:\n"
        "  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: %g, radius: 500,\n"
        "      azimuth: 20, intensity: 3.0e5 }\n"
        "  - { name: l1, modbus-coil: { bus: relays, coil: 1 }, elevation: 55, radius: 500,\n"
        "      azimuth: 140, intensity: 3.0e5 }\n"
        "  - { name: l2, modbus-coil: { bus: relays, coil: 2 }, elevation: 40, radius: 420,\n"
        "      azimuth: 250, intensity: 3.0e5 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 30, distance: 450, azimuth: 0,\n"
        "      target: [0, 0, 30], width: 1024, height: 768, fx: 1600, fy: 1600,\n"
        "      distortion: [-0.08, 0.05, 0.0005, -0.0004, 0], exposure_us: 20000 }\n"
        "  - { name: c1, sim: { bus: frames }, elevation: 40, distance: 480, azimuth: 70,\n"
        "      target: [0, 0, 30], width: 1024, height: 768, fx: 1500, fy: 1500,\n"
        "      exposure_us: 20000 }\n";
const char ls_scene_sphere[] =
        "scene:\n  seed: 3\n"
        "  targets:\n"
        "    - { type: mirror_sphere, size: 100, reflectance: 0.6, pose: { translate: [70, 0, "
        "0] } }\n"
        "  turntable: { radius: 400, albedo: 0.8 }\n"
        "  lamps: { radius: 30 }\n"
        "  sensor: { black_level: 0.02 }\n";
const char ls_scene_empty[] = "scene:\n  seed: 3\n"
                              "  object: { shape: cylinder, size: 60, material: { albedo: 0.5 } }\n"
                              "  turntable: { radius: 400, albedo: 0.8 }\n"
                              "  lamps: { radius: 30 }\n";

const double LS_SPHERE_TRUE[3] = {70, 0, LS_SPHERE_MM / 2};

void ls_open(struct ls_fixture *fx, const char *scene, double l0_elevation)
{
        char lamps[1024];

        memset(fx, 0, sizeof(*fx));
        snprintf(lamps, sizeof(lamps), lamps_fmt, l0_elevation);
        rt_open(&fx->t, lamps, "", cams, scene);
        for (size_t i = 0; i < fx->t.rc->n_cameras; i++) {
                const struct rig_camera_conf *cc = &fx->t.rc->cameras[i];
                struct sec_camera *c = &fx->cams[i].cal;
                snprintf(fx->cams[i].name, sizeof(fx->cams[i].name), "%s", cc->name);
                c->k = (struct cal_intrinsics){
                        .fx = cc->fx, .fy = cc->fy, .cx = cc->cx, .cy = cc->cy};
                memcpy(c->k.dist, cc->dist, sizeof(c->k.dist));
                c->width = cc->width;
                c->height = cc->height;
                riggeom_camera_pose(cc, 0, c->R, c->t);
        }
        fx->o = (struct cal_lamps_opts){.rc = fx->t.rc,
                                        .cams = fx->cams,
                                        .n_cams = fx->t.rc->n_cameras,
                                        .sphere_mm = LS_SPHERE_MM,
                                        .lamp_radius_mm = LS_LAMP_RADIUS_MM};
}

void ls_close(struct ls_fixture *fx)
{
        rt_close(&fx->t);
}

void ls_render(struct ls_fixture *fx, int cam, double tt, double arm, uint32_t lit,
               struct gn_frame *f)
{
        struct gn_pose st = {{tt, arm, NAN}, lit, false};
        char name[64];

        CHECK_INT(sim_render(fx->t.s, &st, cam, NULL, ++fx->seq, f, 0, NULL), 0);
        snprintf(name, sizeof(name), "lamps-c%d-%03.0f-%u", cam, tt, lit);
        rt_dump(f, name); /* RTEST_DUMP=dir keeps the views */
}

/* Stores a view of camera cam, angle tt, lamp `lamp` lit in the pose recorded; `lit` are the
 * lamps actually lit when rendering. */
static void store(struct ls_fixture *fx, struct ds *d, int cam, double tt, int lamp, uint32_t lit)
{
        struct gn_frame f;
        struct ds_capture c = {.pose = {{tt, NAN, NAN}, 1u << lamp, false}, .exposure_us = 20000};

        snprintf(c.camera, sizeof(c.camera), "%s", fx->cams[cam].name);
        snprintf(c.lamps, sizeof(c.lamps), "%s", fx->t.rc->lamps[lamp].name);
        ls_render(fx, cam, tt, NAN, lit, &f);
        CHECK_INT(ds_store(d, &f, &c), 0);
        gn_frame_free_data(&f);
}

struct ds *ls_make_dataset(struct ls_fixture *fx, const char *path, int angles, int n_lamps,
                           int off)
{
        _cleanup_free_ char *rig = NULL;
        size_t len;
        struct ds *d;

        CHECK_INT(gn_read_file_at(AT_FDCWD, fx->t.path, 1 << 20, (void **)&rig, &len), 0);
        CHECK_INT(ds_create(path, "lamps", rig, &d), 0);
        for (int a = 0; a < angles; a++)
                for (int cam = 0; cam < 2; cam++)
                        for (int lamp = 0; lamp < n_lamps; lamp++)
                                store(fx, d, cam, 360.0 * a / angles, lamp,
                                      lamp == off ? 0 : 1u << lamp);
        return d;
}

double ls_lamp_error(const struct ls_fixture *fx, int lamp, const double pos[3])
{
        struct gn_pose st = {{0, 0, NAN}, 0, false};
        double truth[3];

        CHECK_INT(sim_lamp_position(fx->t.s, &st, lamp, truth), 0);
        return hypot(hypot(pos[0] - truth[0], pos[1] - truth[1]), pos[2] - truth[2]);
}
