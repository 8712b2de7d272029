/* scene.c - the scene section of the rig file (docs/sim-render.md): object, calibration
 * targets, turntable disc, materials, lamp size, dome, sensor. Every mapping is checked
 * for unknown keys; errors name the file, the line and the key. */
#include <errno.h>
#include <libfyaml.h>
#include <libgen.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "common/cleanup.h"
#include "internal.h"

struct pose {
        double R[9], t[3];
};

static int parse_pose(struct yconf *y, struct fy_node *parent, struct pose *p)
{
        static const char *const keys[] = {"translate", "rotate_x", "rotate_y", "rotate_z", NULL};
        struct fy_node *map = yconf_get(parent, "pose");
        double ang[3] = {0}, Rx[9], Ry[9], Rz[9], Ryx[9];
        int r;

        memset(p->t, 0, sizeof(p->t));
        if (map) {
                if ((r = yconf_check_keys(y, map, keys)) < 0 ||
                    (r = yconf_doubles(y, map, "translate", p->t, 3, 3, NULL)) < 0 ||
                    (r = yconf_double(y, map, "rotate_x", -360, 360, &ang[0])) < 0 ||
                    (r = yconf_double(y, map, "rotate_y", -360, 360, &ang[1])) < 0 ||
                    (r = yconf_double(y, map, "rotate_z", -360, 360, &ang[2])) < 0)
                        return r;
        }
        /* R = Rz * Ry * Rx (x first) */
        double cx = cos(ang[0] * M_PI / 180), sx = sin(ang[0] * M_PI / 180);
        double cy = cos(ang[1] * M_PI / 180), sy = sin(ang[1] * M_PI / 180);
        double rx[9] = {1, 0, 0, 0, cx, -sx, 0, sx, cx};
        double ry[9] = {cy, 0, sy, 0, 1, 0, -sy, 0, cy};
        memcpy(Rx, rx, sizeof(Rx));
        memcpy(Ry, ry, sizeof(Ry));
        m3d_rot_z(ang[2], Rz);
        m3d_mul(Ry, Rx, Ryx);
        m3d_mul(Rz, Ryx, p->R);
        return 0;
}

/* An RGB value given as a number or a list of 1 or 3 numbers in [0, 1]. */
static int parse_rgb(struct yconf *y, struct fy_node *map, const char *key, float out[3])
{
        struct fy_node *n = yconf_get(map, key);
        double v[3];
        size_t cnt = 0;
        int r;

        if (!n)
                return 0;
        if (fy_node_is_scalar(n)) {
                r = yconf_double(y, map, key, 0, 1, &v[0]);
                cnt = 1;
        } else {
                r = yconf_doubles(y, map, key, v, 1, 3, &cnt);
                if (r >= 0 && cnt == 2)
                        return yconf_error(y, n, key, "expected 1 or 3 values");
                for (size_t i = 0; r >= 0 && i < cnt; i++)
                        if (v[i] < 0 || v[i] > 1)
                                return yconf_error(y, n, key, "values must be in [0, 1]");
        }
        if (r < 0)
                return r;
        for (int i = 0; i < 3; i++)
                out[i] = (float)v[cnt == 3 ? i : 0];
        return 1;
}

enum map_kind { MAP_LINEAR, MAP_SRGB, MAP_ENV };

/* The image named by key (a path relative to the rig file), if given. Returns 1, 0 (no key)
 * or a yconf error. */
static int load_map(struct sim_scene *s, struct yconf *y, struct fy_node *map, const char *key,
                    enum map_kind kind, struct rtex **out)
{
        char rel[RIG_PATH_MAX], path[2 * RIG_PATH_MAX], dir[RIG_PATH_MAX];
        int r = yconf_str(y, map, key, rel, sizeof(rel));

        if (r <= 0)
                return r;
        snprintf(dir, sizeof(dir), "%s", s->rc->path);
        if (rel[0] == '/')
                snprintf(path, sizeof(path), "%s", rel);
        else
                snprintf(path, sizeof(path), "%s/%s", dirname(dir), rel);
        r = kind == MAP_ENV ? rtex_load_env(path, out) : rtex_load_png(path, kind == MAP_SRGB, out);
        if (r < 0)
                return yconf_error(y, yconf_get(map, key), key, "cannot load %s '%s': %s",
                                   kind == MAP_ENV ? "PNG or PFM" : "PNG", path, strerror(-r));
        return 1;
}

static int parse_specular(struct sim_scene *s, struct yconf *y, struct fy_node *map, struct rmat *m)
{
        static const char *const keys[] = {"model", "ks",     "alpha",     "alpha_x", "alpha_y",
                                           "ior",   "ks_map", "alpha_map", NULL};
        static const char *const models[] = {"none", "ward", "beckmann", "mirror"};
        char model[16] = "beckmann";
        double ks = 0.2, a = 0.2, ax = -1, ay = -1, ior = 0;
        int r;

        if ((r = yconf_check_keys(y, map, keys)) < 0 ||
            (r = yconf_str(y, map, "model", model, sizeof(model))) < 0 ||
            (r = yconf_double(y, map, "ks", 0, 1, &ks)) < 0 ||
            (r = yconf_double(y, map, "alpha", 1e-3, 2, &a)) < 0 ||
            (r = yconf_double(y, map, "alpha_x", 1e-3, 2, &ax)) < 0 ||
            (r = yconf_double(y, map, "alpha_y", 1e-3, 2, &ay)) < 0 ||
            (r = yconf_double(y, map, "ior", 0, 10, &ior)) < 0 ||
            (r = load_map(s, y, map, "ks_map", MAP_LINEAR, &m->ks_map)) < 0 ||
            (r = load_map(s, y, map, "alpha_map", MAP_LINEAR, &m->alpha_map)) < 0)
                return r;
        m->model = (enum spec_model)ELEMENTSOF(models);
        for (size_t i = 0; i < ELEMENTSOF(models); i++)
                if (!strcmp(model, models[i]))
                        m->model = (enum spec_model)i;
        if (m->model == (enum spec_model)ELEMENTSOF(models))
                return yconf_error(y, yconf_get(map, "model"), "model",
                                   "expected none, ward, beckmann or mirror");
        if (ior > 0 && ior < 1)
                return yconf_error(y, yconf_get(map, "ior"), "ior", "must be 0 (off) or >= 1");
        m->ks = (float)ks;
        m->ax = (float)(ax > 0 ? ax : a);
        m->ay = (float)(ay > 0 ? ay : a);
        m->f0 = ior > 0 ? (float)pow((ior - 1) / (ior + 1), 2) : 1.0f;
        return 0;
}

static int parse_material(struct sim_scene *s, struct yconf *y, struct fy_node *parent,
                          struct rmat *m)
{
        static const char *const keys[] = {"albedo", "albedo_map", "specular", NULL};
        struct fy_node *map = yconf_get(parent, "material"), *spec;
        int r;

        if (!map)
                return 0;
        if ((r = yconf_check_keys(y, map, keys)) < 0 ||
            (r = parse_rgb(y, map, "albedo", m->albedo)) < 0 ||
            (r = load_map(s, y, map, "albedo_map", MAP_SRGB, &m->albedo_map)) < 0)
                return r;
        spec = yconf_get(map, "specular");
        return spec ? parse_specular(s, y, spec, m) : 0;
}

static struct rgeom *new_geom(struct sim_scene *s, enum geom_kind kind)
{
        struct rgeom *g;

        if (s->n_geoms == SIM_MAX_GEOMS)
                return NULL;
        g = &s->geoms[s->n_geoms++];
        memset(g, 0, sizeof(*g));
        g->kind = kind;
        g->mat = s->n_mats++;
        s->mats[g->mat] = (struct rmat){
                .model = SPEC_NONE, .albedo = {0.5f, 0.5f, 0.5f}, .ax = 0.2f, .ay = 0.2f, .f0 = 1};
        return g;
}

/* Places a geometry (shape frame -> object frame by pose): mesh, local frame, axis. */
static void place(struct rgeom *g, const struct pose *p)
{
        for (int i = 0; i < 3; i++) {
                double ti = 0;
                for (int j = 0; j < 3; j++) {
                        g->to_local[i * 4 + j] = (float)p->R[j * 3 + i];
                        ti -= p->R[j * 3 + i] * p->t[j];
                }
                g->to_local[i * 4 + 3] = (float)ti;
                g->axis[i] = (float)p->R[i * 3 + 2];
        }
        if (g->kind == GEOM_MESH) {
                mesh_transform(&g->mesh, p->R, p->t);
        } else {
                double c[3] = {0, 0, g->radius}, q[3];
                m3d_apply(p->R, c, q);
                for (int i = 0; i < 3; i++)
                        g->centre[i] = (float)(q[i] + p->t[i]);
        }
}

static int build_shape(struct sim_scene *s, struct yconf *y, struct fy_node *map, struct rgeom *g,
                       const char *shape, double size, long res)
{
        char rel[RIG_PATH_MAX], path[2 * RIG_PATH_MAX], dir[RIG_PATH_MAX], err[512];
        int r = 0;

        g->uv_size = (float)size;
        g->uvmap = UV_MESH;
        if (!strcmp(shape, "sphere") && res == 0) {
                g->kind = GEOM_SPHERE;
                g->radius = (float)size / 2;
                g->uvmap = UV_SPHERE;
        } else if (!strcmp(shape, "sphere")) {
                r = shape_sphere_mesh((float)size / 2, (int)res, &g->mesh);
        } else if (!strcmp(shape, "cylinder")) {
                r = shape_cylinder((float)size / 2, (float)size, res ? (int)res : 512, &g->mesh);
        } else if (!strcmp(shape, "gem")) {
                r = shape_gem((float)size, res ? (int)res : 16, &g->mesh);
                g->uvmap = UV_PLANAR;
        } else if (!strcmp(shape, "relief")) {
                r = shape_relief((float)size, res ? (int)res : 96, &g->mesh);
        } else if (!strcmp(shape, "mesh")) {
                if ((r = yconf_str_req(y, map, "path", rel, sizeof(rel))) < 0)
                        return r;
                snprintf(dir, sizeof(dir), "%s", s->rc->path);
                snprintf(path, sizeof(path), "%s/%s", rel[0] == '/' ? "" : dirname(dir), rel);
                r = mesh_load(path, &g->mesh, err, sizeof(err));
                if (r < 0)
                        return yconf_error(y, yconf_get(map, "path"), "path", "%s", err);
                if (size > 0)
                        mesh_fit(&g->mesh, (float)size);
                g->uvmap = g->mesh.uv ? UV_MESH : UV_PLANAR;
        } else {
                return yconf_error(y, yconf_get(map, "shape"), "shape",
                                   "expected sphere, cylinder, gem, relief or mesh");
        }
        return r < 0 ? yconf_error(y, map, "shape", "cannot build: %s", strerror(-r)) : 0;
}

static int parse_object(struct sim_scene *s, struct yconf *y, struct fy_node *map)
{
        static const char *const keys[] = {"shape",  "size", "resolution", "path",
                                           "smooth", "pose", "material",   NULL};
        char shape[16] = "sphere";
        double size = 0;
        long res = 0;
        bool smooth = false;
        struct pose p;
        struct rgeom *g = new_geom(s, GEOM_MESH);
        int r;

        if (!g)
                return yconf_error(y, map, "object", "too many geometries");
        if ((r = yconf_check_keys(y, map, keys)) < 0 ||
            (r = yconf_str(y, map, "shape", shape, sizeof(shape))) < 0 ||
            (r = yconf_double(y, map, "size", 0.1, 5000, &size)) < 0 ||
            (r = yconf_int(y, map, "resolution", 0, 4096, &res)) < 0 ||
            (r = yconf_bool(y, map, "smooth", &smooth)) < 0 || (r = parse_pose(y, map, &p)) < 0 ||
            (r = parse_material(s, y, map, &s->mats[g->mat])) < 0)
                return r;
        if (size == 0 && strcmp(shape, "mesh"))
                return yconf_error(y, map, "size", "required for shape '%s'", shape);
        if ((r = build_shape(s, y, map, g, shape, size, res)) < 0)
                return r;
        if (smooth && g->kind == GEOM_MESH && (r = mesh_smooth_normals(&g->mesh)) < 0)
                return r;
        place(g, &p);
        s->has_object = true;
        return 0;
}

static int parse_board(struct sim_scene *s, struct yconf *y, struct fy_node *map, struct rgeom *g,
                       bool charuco)
{
        struct board *b = &s->boards[s->n_boards++];
        double sq[2] = {0}, square = 20, marker = 0, margin = -1, white = 0.85, black = 0.03;
        long first = 0;
        int r;

        if ((r = yconf_doubles(y, map, "squares", sq, 2, 2, NULL)) < 0 ||
            (r = yconf_double(y, map, "square", 0.1, 1000, &square)) < 0 ||
            (r = yconf_double(y, map, "marker", 0, 1000, &marker)) < 0 ||
            (r = yconf_double(y, map, "margin", 0, 1000, &margin)) < 0 ||
            (r = yconf_double(y, map, "white", 0, 1, &white)) < 0 ||
            (r = yconf_double(y, map, "black", 0, 1, &black)) < 0 ||
            (r = yconf_int(y, map, "first_id", 0, 49, &first)) < 0)
                return r;
        if (sq[0] < 2 || sq[1] < 2 || sq[0] > 100 || sq[1] > 100 || sq[0] != floor(sq[0]) ||
            sq[1] != floor(sq[1]))
                return yconf_error(y, yconf_get(map, "squares"), "squares",
                                   "expected [columns, rows], integers in [2, 100]");
        *b = (struct board){charuco ? BOARD_CHARUCO : BOARD_CHESS,
                            (int)sq[0],
                            (int)sq[1],
                            (float)square,
                            (float)(marker > 0 ? marker : 0.75 * square),
                            (float)(margin >= 0 ? margin : square),
                            (float)white,
                            (float)black,
                            (int)first};
        if (charuco && b->marker >= b->square)
                return yconf_error(y, map, "marker", "must be smaller than the square");
        if (charuco && b->first_id + (b->nx * b->ny) / 2 > 50)
                return yconf_error(y, map, "squares", "more markers than DICT_4X4_50 holds");
        g->board = b;
        g->uvmap = UV_PLANAR;
        g->uv_size = 1;
        return shape_rect(-b->margin, -b->margin, b->nx * b->square + b->margin,
                          b->ny * b->square + b->margin, &g->mesh);
}

static int parse_target(struct sim_scene *s, struct yconf *y, struct fy_node *map)
{
        static const char *const keys[] = {"type",   "squares",     "square", "marker",
                                           "margin", "white",       "black",  "first_id",
                                           "size",   "reflectance", "pose",   NULL};
        char type[16] = "";
        double size = 50, refl = 0.9;
        struct pose p;
        struct rgeom *g = new_geom(s, GEOM_MESH);
        int r;

        if (!g || s->n_targets == SIM_MAX_TARGETS)
                return yconf_error(y, map, "targets", "too many targets");
        if ((r = yconf_check_keys(y, map, keys)) < 0 ||
            (r = yconf_str_req(y, map, "type", type, sizeof(type))) < 0 ||
            (r = yconf_double(y, map, "size", 0.1, 1000, &size)) < 0 ||
            (r = yconf_double(y, map, "reflectance", 0, 1, &refl)) < 0 ||
            (r = parse_pose(y, map, &p)) < 0)
                return r;
        if (!strcmp(type, "chessboard") || !strcmp(type, "charuco")) {
                r = parse_board(s, y, map, g, type[1] == 'h' && type[2] == 'a');
        } else if (!strcmp(type, "mirror_sphere")) {
                g->kind = GEOM_SPHERE;
                g->radius = (float)size / 2;
                g->uvmap = UV_SPHERE;
                g->uv_size = (float)size;
                s->mats[g->mat] = (struct rmat){
                        .model = SPEC_MIRROR, .ks = (float)refl, .ax = 1, .ay = 1, .f0 = 1};
        } else {
                return yconf_error(y, yconf_get(map, "type"), "type",
                                   "expected chessboard, charuco or mirror_sphere");
        }
        if (r < 0)
                return r == -EINVAL ? r : yconf_error(y, map, "type", "%s", strerror(-r));
        place(g, &p);
        memcpy(s->target_R[s->n_targets], p.R, sizeof(p.R));
        memcpy(s->target_t[s->n_targets], p.t, sizeof(p.t));
        s->n_targets++;
        return 0;
}

int sim_target_pose(const struct sim_scene *s, const struct gn_pose *st, int target, double R[9],
                    double t[3])
{
        double Rz[9];

        if (!s || !st || target < 0 || target >= s->n_targets)
                return -EINVAL;
        m3d_rot_z(pose_deg(st, GN_ROLE_TURNTABLE), Rz);
        m3d_mul(Rz, s->target_R[target], R);
        m3d_apply(Rz, s->target_t[target], t);
        return 0;
}

static int parse_targets(struct sim_scene *s, struct yconf *y, struct fy_node *seq)
{
        int n = yconf_seq_len(y, seq, "targets"), r;

        for (int i = 0; i < n; i++)
                if ((r = parse_target(s, y, yconf_seq_item(seq, i))) < 0)
                        return r;
        return n < 0 ? n : 0;
}

static int parse_turntable(struct sim_scene *s, struct yconf *y, struct fy_node *map)
{
        static const char *const keys[] = {"radius", "material", "albedo", NULL};
        double radius = 150;
        struct pose p = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, 0, 0}};
        struct rgeom *g;
        int r;

        if (map && ((r = yconf_check_keys(y, map, keys)) < 0 ||
                    (r = yconf_double(y, map, "radius", 0, 5000, &radius)) < 0))
                return r;
        if (radius <= 0)
                return 0;
        g = new_geom(s, GEOM_MESH);
        if (!g)
                return yconf_error(y, map, "turntable", "too many geometries");
        s->mats[g->mat].albedo[0] = s->mats[g->mat].albedo[1] = s->mats[g->mat].albedo[2] = 0.2f;
        if (map && ((r = parse_rgb(y, map, "albedo", s->mats[g->mat].albedo)) < 0 ||
                    (r = parse_material(s, y, map, &s->mats[g->mat])) < 0))
                return r;
        g->uvmap = UV_PLANAR;
        g->uv_size = (float)(2 * radius);
        r = shape_disc((float)radius, 256, &g->mesh);
        if (r < 0)
                return r;
        place(g, &p);
        return 0;
}

static int parse_dome(struct sim_scene *s, struct yconf *y, struct fy_node *root)
{
        static const char *const keys[] = {"radiance",     "zenith_ratio", "ground", "threshold",
                                           "max_elements", "envmap",       NULL};
        struct fy_node *map = yconf_get(root, "dome");
        struct dome *d = &s->dome;
        long maxel = 256;
        int r;

        *d = (struct dome){.zenith_ratio = 1, .threshold = 1.0 / 64};
        if (!root)
                return 0;
        if ((r = yconf_double(y, root, "ambient", 0, 1e9, &d->radiance)) < 0)
                return r;
        if (map && ((r = yconf_check_keys(y, map, keys)) < 0 ||
                    (r = yconf_double(y, map, "radiance", 0, 1e9, &d->radiance)) < 0 ||
                    (r = yconf_double(y, map, "zenith_ratio", 0, 100, &d->zenith_ratio)) < 0 ||
                    (r = yconf_double(y, map, "ground", 0, 10, &d->ground)) < 0 ||
                    (r = yconf_double(y, map, "threshold", 1e-5, 1, &d->threshold)) < 0 ||
                    (r = yconf_int(y, map, "max_elements", 8, SIM_MAX_DOME, &maxel)) < 0))
                return r;
        d->max_elements = (int)maxel;
        if (map && (r = load_map(s, y, map, "envmap", MAP_ENV, &d->env)) < 0)
                return r;
        if (d->env && d->env->w != 2 * d->env->h)
                return yconf_error(y, yconf_get(map, "envmap"), "envmap",
                                   "not a latitude-longitude map: %dx%d (the width must be twice "
                                   "the height)",
                                   d->env->w, d->env->h);
        if (d->env && !yconf_get(map, "radiance"))
                d->radiance = 1;
        return d->radiance > 0 ? dome_build(d, &s->dome_els, &s->n_dome) : 0;
}

static int parse_lamps(struct sim_scene *s, struct yconf *y, struct fy_node *map)
{
        static const char *const keys[] = {"radius", "samples", NULL};
        long n = 1;
        int r;

        s->lamp_radius = 5;
        if (!map)
                return (s->lamp_samples = 1);
        if ((r = yconf_check_keys(y, map, keys)) < 0 ||
            (r = yconf_double(y, map, "radius", 0, 1000, &s->lamp_radius)) < 0 ||
            (r = yconf_int(y, map, "samples", 1, SIM_MAX_LAMP_SAMPLES, &n)) < 0)
                return r;
        s->lamp_samples = (int)n;
        return 0;
}

static int parse_sensor(struct sim_scene *s, struct yconf *y, struct fy_node *map)
{
        static const char *const keys[] = {"response",   "full_well", "read_noise", "black_level",
                                           "shot_noise", "format",    NULL};
        struct sensor *se = &s->sensor;
        char fmt[16] = "rgb";
        int r;

        *se = (struct sensor){5e5, 10000, 3, 0, true, FMT_RGB};
        if (!map)
                return 0;
        if ((r = yconf_check_keys(y, map, keys)) < 0 ||
            (r = yconf_double(y, map, "response", 0, 1e12, &se->response)) < 0 ||
            (r = yconf_double(y, map, "full_well", 1, 1e9, &se->full_well)) < 0 ||
            (r = yconf_double(y, map, "read_noise", 0, 1e6, &se->read_noise)) < 0 ||
            (r = yconf_double(y, map, "black_level", 0, 0.5, &se->black)) < 0 ||
            (r = yconf_bool(y, map, "shot_noise", &se->shot_noise)) < 0 ||
            (r = yconf_str(y, map, "format", fmt, sizeof(fmt))) < 0)
                return r;
        if (!strcmp(fmt, "rgb") || !strcmp(fmt, "mono") || !strcmp(fmt, "rggb"))
                se->format = fmt[0] == 'm'                    ? FMT_MONO
                             : fmt[1] == 'g' && fmt[2] == 'g' ? FMT_RGGB
                                                              : FMT_RGB;
        else
                return yconf_error(y, yconf_get(map, "format"), "format",
                                   "expected rgb, mono or rggb");
        return 0;
}

int scene_parse(struct sim_scene *s, char *err, size_t errlen)
{
        static const char *const keys[] = {"seed",    "threads", "object", "targets", "turntable",
                                           "ambient", "dome",    "lamps",  "sensor",  NULL};
        struct yconf y = s->rc->yc;
        struct fy_node *root = rigconf_scene(s->rc), *n;
        long seed = 0, threads = 0;
        int r;

        y.err = err;
        y.errlen = errlen;
        if (root && ((r = yconf_check_keys(&y, root, keys)) < 0 ||
                     (r = yconf_int(&y, root, "seed", 0, INT64_MAX, &seed)) < 0 ||
                     (r = yconf_int(&y, root, "threads", 0, 64, &threads)) < 0))
                return r;
        s->seed = (uint64_t)seed;
        s->threads = (int)threads;
        if ((n = yconf_get(root, "object")) && (r = parse_object(s, &y, n)) < 0)
                return r;
        if ((n = yconf_get(root, "targets")) && (r = parse_targets(s, &y, n)) < 0)
                return r;
        if ((r = parse_turntable(s, &y, yconf_get(root, "turntable"))) < 0 ||
            (r = parse_dome(s, &y, root)) < 0 ||
            (r = parse_lamps(s, &y, yconf_get(root, "lamps"))) < 0 ||
            (r = parse_sensor(s, &y, yconf_get(root, "sensor"))) < 0)
                return r;
        return 0;
}
