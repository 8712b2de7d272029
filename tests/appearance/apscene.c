/* apscene.c - synthetic 4-DOF datasets for the appearance tests (apscene.h). */
#include <fcntl.h>
#include <math.h>
#include <stdio.h>

#include "appearance/fit.h"
#include "calib/ply.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "drivers/registry.h"
#include "tests/appearance/apscene.h"

#define DEG        (M_PI / 180)
#define EXPOSURE   20000 /* us: 1 radiance unit is full scale (sensor defaults) */
#define CAM_DIST   400.0
#define MESH_RINGS 48

static const double cam_elevation[APS_MAX_CAMERAS] = {15, 35, 55};

void aps_opts_default(struct aps_opts *o, enum aps_material m)
{
        static const double alpha[] = {[APS_DIFFUSE] = 0,
                                       [APS_ROUGH] = 0.5,
                                       [APS_GLOSSY] = 0.3,
                                       [APS_SHINY] = 0.2,
                                       [APS_SHARP] = 0.12};

        *o = (struct aps_opts){.width = 96,
                               .height = 72,
                               .n_cameras = 1,
                               .turntable_angles = 2,
                               .arm_angles = 18,
                               .n_lamps = 6,
                               .lamp_elevation_deg = {-40, -15, 10, 35, 60, 85},
                               .lamp_radius_mm = 500,
                               .intensity = 7e5,
                               .shape = "sphere",
                               .albedo = {0.7, 0.55, 0.4},
                               .ks = m == APS_DIFFUSE ? 0 : 0.25,
                               .alpha = alpha[m],
                               .mesh = true,
                               .mesh_rings = MESH_RINGS};
}

/* The lamps section: o's lamps and the probe, all at azimuth 0 of the arm. */
static void lamps_yaml(const struct aps_opts *o, char *buf, size_t len)
{
        size_t n = (size_t)snprintf(buf, len, "lamps:\n");

        for (int i = 0; i <= o->n_lamps && n < len; i++)
                n += (size_t)snprintf(buf + n, len - n,
                                      "  - { name: %s%d, modbus-coil: { bus: relays, coil: %d },"
                                      " elevation: %g, radius: %g, azimuth: 0, intensity: %g }\n",
                                      i < o->n_lamps ? "l" : "probe", i, i,
                                      i < o->n_lamps ? o->lamp_elevation_deg[i] : 0,
                                      o->lamp_radius_mm, o->intensity);
        CHECK(n < len);
}

static void cameras_yaml(const struct aps_opts *o, char *buf, size_t len)
{
        size_t n = (size_t)snprintf(buf, len, "cameras:\n");
        double f = 4.0 * o->width;
        const double *k = o->dist;
        char dist[160] = ""; /* only when there is one: tests add their own to the rig text */

        if (k[0] || k[1] || k[2] || k[3] || k[4])
                snprintf(dist, sizeof(dist), ", distortion: [%g, %g, %g, %g, %g]", k[0], k[1], k[2],
                         k[3], k[4]);
        for (int i = 0; i < o->n_cameras && n < len; i++)
                n += (size_t)snprintf(buf + n, len - n,
                                      "  - { name: c%d, sim: { bus: frames }, elevation: %g,"
                                      " distance: %g, azimuth: 0, target: [0, 0, %g], width: %d,"
                                      " height: %d, fx: %g, fy: %g, exposure_us: %d%s }\n",
                                      i, cam_elevation[i], CAM_DIST, APS_SIZE_MM / 2, o->width,
                                      o->height, f, f, EXPOSURE, dist);
        CHECK(n < len);
}

static void scene_yaml(const struct aps_opts *o, char *buf, size_t len)
{
        char spec[200] = "{ model: none }";

        if (o->ks > 0)
                snprintf(spec, sizeof(spec),
                         "{ model: beckmann, ks: %g, alpha_x: %g, alpha_y: %g, ior: 1.5 }", o->ks,
                         o->alpha, o->alpha_y > 0 ? o->alpha_y : o->alpha);
        CHECK(snprintf(buf, len,
                       "scene:\n  seed: 1\n"
                       "  object: { shape: %s, size: %g, material: { albedo: [%g, %g, %g],"
                       " specular: %s } }\n"
                       "  turntable: { radius: 0 }\n",
                       o->shape, APS_SIZE_MM, o->albedo[0], o->albedo[1], o->albedo[2],
                       spec) < (int)len);
}

void aps_open(struct apscene *s, const struct aps_opts *o)
{
        char lamps[2048], cams[1024], scene[512];

        CHECK(o->n_lamps >= 0 && o->n_lamps <= APS_MAX_LAMPS);
        CHECK(o->n_cameras >= 1 && o->n_cameras <= APS_MAX_CAMERAS);
        memset(s, 0, sizeof(*s));
        s->o = *o;
        s->probe = o->n_lamps;
        lamps_yaml(o, lamps, sizeof(lamps));
        cameras_yaml(o, cams, sizeof(cams));
        scene_yaml(o, scene, sizeof(scene));
        rt_open(&s->t, lamps, "", cams, scene);
}

void aps_close(struct apscene *s)
{
        rt_close(&s->t);
}

static void render(struct apscene *s, int cam, double tt, double arm, int lamp, struct gn_frame *f,
                   unsigned flags, struct sim_truth *truth)
{
        struct gn_pose st = {{tt, arm, NAN}, 1u << lamp, false};
        struct sim_expose ex = {.bits = 16, .no_noise = !s->o.noise};

        CHECK_INT(sim_render(s->t.s, &st, cam, &ex, ++s->seq, f, flags, truth), 0);
}

void aps_render_lamp(struct apscene *s, int cam, double tt, double arm, int lamp,
                     struct gn_frame *f, unsigned flags, struct sim_truth *truth)
{
        CHECK(lamp >= 0 && lamp < s->o.n_lamps);
        render(s, cam, tt, arm, lamp, f, flags, truth);
}

void aps_render_light(struct apscene *s, int cam, double tt, const double p[3], struct gn_frame *f,
                      unsigned flags, struct sim_truth *truth)
{
        struct rig_switch_conf *l = &s->t.rc->lamps[s->probe];
        double r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);

        /* the renderer places lamps from the rig config at each frame */
        l->radius_mm = r;
        l->elevation_deg = asin(p[2] / r) / DEG;
        l->azimuth_deg = atan2(p[1], p[0]) / DEG;
        render(s, cam, tt, 0, s->probe, f, flags, truth);
}

void aps_render_view(struct apscene *s, int cam, double elevation_deg, double tt, const double p[3],
                     struct gn_frame *f, unsigned flags, struct sim_truth *truth)
{
        struct rig_camera_conf *cc = &s->t.rc->cameras[cam];
        double keep = cc->elevation_deg;

        CHECK(cam >= 0 && cam < s->o.n_cameras);
        cc->elevation_deg = elevation_deg; /* read by the renderer at each frame */
        aps_render_light(s, cam, tt, p, f, flags, truth);
        cc->elevation_deg = keep;
}

void aps_lamp_position(const struct apscene *s, int lamp, double arm, double p[3])
{
        struct gn_pose st = {{0, arm, NAN}, 0, false};

        CHECK_INT(sim_lamp_position(s->t.s, &st, lamp, p), 0);
}

void aps_write_mesh(const struct apscene *s, const char *dir)
{
        const int rings = s->o.mesh_rings, segs = 2 * s->o.mesh_rings;
        struct cal_mesh m = {0};
        double r = APS_SIZE_MM / 2;
        _cleanup_close_ int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);

        if (strcmp(s->o.shape, "sphere") != 0)
                return;
        m.v = calloc((size_t)(rings + 1) * segs, sizeof(*m.v));
        m.tri = calloc((size_t)rings * segs * 6, sizeof(*m.tri));
        CHECK(m.v && m.tri && fd >= 0);
        for (int i = 0; i <= rings; i++)
                for (int j = 0; j < segs; j++) {
                        double th = M_PI * i / rings, ph = 2 * M_PI * j / segs;
                        double n[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
                        struct sec_point *v = &m.v[m.n_v++];
                        for (int k = 0; k < 3; k++) {
                                v->n[k] = (float)n[k];
                                v->x[k] = (float)(r * n[k] + (k == 2 ? r : 0));
                        }
                }
        for (int i = 0; i < rings; i++)
                for (int j = 0; j < segs; j++) {
                        uint32_t a = i * segs + j, b = i * segs + (j + 1) % segs;
                        uint32_t c = a + segs, d = b + segs, q[6] = {a, c, b, b, c, d};
                        memcpy(m.tri + 3 * m.n_tri, q, sizeof(q));
                        m.n_tri += 2;
                }
        CHECK_INT(ply_write_mesh(fd, "mesh.ply", &m), 0);
        cal_mesh_free(&m);
}

static void store(struct apscene *s, struct ds *d, int cam, double tt, double arm, int lamp)
{
        struct ds_capture c = {.pose = {{tt, arm, NAN}, 1u << lamp, false},
                               .exposure_us = EXPOSURE};
        struct gn_frame f;

        snprintf(c.camera, sizeof(c.camera), "%s", s->t.rc->cameras[cam].name);
        snprintf(c.lamps, sizeof(c.lamps), "%s", s->t.rc->lamps[lamp].name);
        aps_render_lamp(s, cam, tt, arm, lamp, &f, 0, NULL);
        CHECK_INT(ds_store(d, &f, &c), 0);
        gn_frame_free_data(&f);
}

struct ds *aps_make_dataset(struct apscene *s, const char *path)
{
        const struct aps_opts *o = &s->o;
        _cleanup_free_ char *rig = NULL;
        size_t len;
        struct ds *d;

        CHECK_INT(gn_read_file_at(AT_FDCWD, s->t.path, 1 << 20, (void **)&rig, &len), 0);
        CHECK_INT(ds_create(path, "apscene", rig, &d), 0);
        for (int cam = 0; cam < o->n_cameras; cam++)
                for (int v = 0; v < o->turntable_angles; v++)
                        for (int a = 0; a < o->arm_angles; a++)
                                for (int l = 0; l < o->n_lamps; l++)
                                        store(s, d, cam, 360.0 * v / o->turntable_angles,
                                              o->arm_offset_deg + 360.0 * a / o->arm_angles, l);
        if (o->mesh)
                aps_write_mesh(s, path);
        return d;
}

void aps_fit_dataset(struct apscene *s, const char *path, int tile, struct ap_model **m)
{
        struct ds *d = aps_make_dataset(s, path);
        struct ap_fit_opts o;
        char err[512];

        ap_fit_opts_default(&o);
        o.backends = registry_backends;
        o.tile = tile;
        CHECK_INT(ap_fit(d, &o, m, err, sizeof(err)), 0);
        CHECK_INT(ap_model_write(*m, path), 0);
        ds_close(d);
}
