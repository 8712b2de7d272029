/* viewer-fixture.c - the models of the viewer's tests (test-viewer.py).
 *
 *   viewer-fixture DIR         a glossy 60 mm sphere (apscene.h) seen by two cameras at 8
 *                              turntable angles (16 views, so that the views' triangulation has
 *                              faces and a boundary) through a lens with distortion, under 6
 *                              lamps at 12 light-arm angles, fitted into DIR/ds/models/default
 *   viewer-fixture DIR brdf    the same with fewer lamps, and beside it the BRDF model of the
 *                              sphere's true material (envscene.h: anisotropic Beckmann lobe)
 *   viewer-fixture render DIR ENVMAP SPHERES GAIN W H FX FY CX CY R0..R8 T0..T2 OUT
 *                              ap_env_render's frame of that BRDF model under ENVMAP in the
 *                              scene the page shows (webexport.h ap_web_env_scene), for that
 *                              camera: OUT.ppm (8 bit, linear times GAIN, as the page draws)
 *                              and OUT.pgm (render_env.h's mask: 1 object, 2 ground, 0 map) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/model.h"
#include "appearance/webexport.h"
#include "tests/appearance/apscene.h"
#include "tests/appearance/envscene.h"

/* envscene's material (ax along the z axis, ay across it) with a response that exposes it */
static const struct envscene_opts brdf_opts = {.width = 96,
                                               .height = 72,
                                               .elevation = 30,
                                               .env_width = 32,
                                               .dome_elements = 16,
                                               .ks = 0.3,
                                               .ax = 0.2,
                                               .ay = 0.12,
                                               .ground_radius = 150,
                                               .mesh_rows = 36};

static void write_brdf(const char *ds)
{
        struct envscene es;

        envscene_open(&es, &brdf_opts);
        snprintf(es.model->name, sizeof(es.model->name), "default");
        es.model->response = 1;
        for (int i = 0; i < es.model->atlas.width * es.model->atlas.height; i++)
                if (!es.model->texels[i].flags) /* no triangle's: as the fit leaves them */
                        es.model->texels[i].flags = AP_BRDF_MASKED;
        CHECK_INT(ap_brdf_write(es.model, ds), 0);
        envscene_close(&es);
}

static void make(const char *dir, bool brdf)
{
        struct aps_opts o;
        struct apscene s;
        struct ap_model *m;
        char path[4096];

        aps_opts_default(&o, APS_GLOSSY);
        o.n_cameras = 2, o.turntable_angles = 8, o.arm_angles = brdf ? 4 : 12;
        o.dist[0] = -4, o.dist[2] = 0.003,
        o.dist[3] = -0.002; /* 1-2 px at the object: the page must undo it */
        aps_open(&s, &o);
        snprintf(path, sizeof(path), "%s/ds", dir);
        aps_fit_dataset(&s, path, 4, &m);
        ap_model_free(m);
        aps_close(&s);
        if (brdf)
                write_brdf(path);
}

static void write_frame(const char *out, const float *rgb, const uint8_t *mask, int w, int h,
                        float gain)
{
        char path[4200];
        FILE *f;

        snprintf(path, sizeof(path), "%s.ppm", out);
        CHECK((f = fopen(path, "wb")) != NULL);
        fprintf(f, "P6\n%d %d\n255\n", w, h);
        for (size_t i = 0; i < 3 * (size_t)w * h; i++)
                fputc((int)lrintf(255 * fminf(fmaxf(rgb[i] * gain, 0), 1)), f);
        fclose(f);
        snprintf(path, sizeof(path), "%s.pgm", out);
        CHECK((f = fopen(path, "wb")) != NULL);
        fprintf(f, "P5\n%d %d\n255\n", w, h);
        fwrite(mask, 1, (size_t)w * h, f);
        fclose(f);
}

static void render(char **a)
{
        struct ap_brdf_model *m;
        struct ap_envmap env;
        struct ap_spheres sp;
        struct ap_prefilter pf;
        struct ap_env_scene sc;
        struct ap_env_renderer *r;
        struct ap_camera cam = {atoi(a[4]), atoi(a[5]), atof(a[6]),
                                atof(a[7]), atof(a[8]), atof(a[9])};
        char dir[4096], err[512];

        for (int i = 0; i < 9; i++)
                cam.R[i] = atof(a[10 + i]);
        for (int i = 0; i < 3; i++)
                cam.t[i] = atof(a[19 + i]);
        snprintf(dir, sizeof(dir), "%s/ds/models/default", a[0]);
        CHECK_INT(ap_brdf_read(dir, &m, err, sizeof(err)), 0);
        CHECK_INT(ap_envmap_load(a[1], &env, err, sizeof(err)), 0);
        CHECK_INT(ap_web_spheres(m, atoi(a[2]), &sp), 0);
        CHECK_INT(ap_web_env_scene(m, &env, &sp, &pf, &sc), 0);
        CHECK_INT(ap_env_renderer_new(&sc, &r), 0);
        size_t n = (size_t)cam.width * cam.height;
        float *rgb = malloc(3 * n * sizeof(float));
        uint8_t *mask = malloc(n);
        CHECK(rgb && mask);
        CHECK_INT(ap_env_render(r, &cam, 2, rgb, mask), 0);
        write_frame(a[22], rgb, mask, cam.width, cam.height, (float)atof(a[3]));
        free(rgb);
        free(mask);
        ap_env_renderer_free(r);
        ap_prefilter_free(&pf);
        ap_spheres_free(&sp);
        ap_envmap_free(&env);
        ap_brdf_model_free(m);
}

int main(int argc, char **argv)
{
        if (argc == 25 && strcmp(argv[1], "render") == 0) {
                render(argv + 2);
                return 0;
        }
        CHECK(argc == 2 || (argc == 3 && strcmp(argv[2], "brdf") == 0));
        make(argv[1], argc == 3);
        return 0;
}
