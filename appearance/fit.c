/* fit.c - the appearance fit of a dataset (fit.h): its rows grouped into views and lights,
 * the geometry (fit_geom.c), the pilot views (every few views) fitted first and their
 * coefficient vectors sampled for the PCA (fit_pca.c), every view fitted and projected
 * (fit_view.c), views in parallel; every fallback stated in the model's notes.
 *
 * DESIGN: the coefficient vectors of a whole seed-scale dataset (76 views x 720 x 480 x 108
 * floats, 11 GB) do not fit in memory, and the basis must be known before any view can be
 * projected. The pilot views (one in AP_PILOT_EVERY, at least one) are fitted first; their
 * vectors are kept (about 60 MB a view at seed scale) for the PCA's sample and projected
 * last: every image is read once. No barrier: the worker that fits the last pilot fits the
 * PCA while the others go on with the next views, keeping their vectors while the basis is
 * not known. Each worker holds one view's L x 3N matrix (about 400 MB at seed scale), kept
 * from view to view: faulting it in afresh for each view cost more than a tenth of the fit
 * (bench/fit). */
#include <cblas.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "appearance/fit_internal.h"
#include "common/cleanup.h"

#define AP_PILOT_EVERY     8
#define MIN_SAMPLE_PER_DIM 50 /* the pilot views' vectors sampled: at least this many x 3M */

DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);

void ap_fit_opts_default(struct ap_fit_opts *o)
{
        *o = (struct ap_fit_opts){.name = "default",
                                  .order = AP_ORDER_DEFAULT,
                                  .k = AP_K_DEFAULT,
                                  .sample = AP_SAMPLE_DEFAULT,
                                  .reg = AP_REG_TIKHONOV,
                                  .reg_param = -1,
                                  .tile = AP_TILE_DEFAULT,
                                  .threads = 2,
                                  .background = 0.01,
                                  .saturation = 0.995};
}

double ap_fit_reg_default(enum ap_reg reg)
{
        return 1e-2; /* both: docs/appearance.md, "Regularisation" */
}

void fit_note(struct fit_ctx *c, const char *fmt, ...)
{
        size_t len = strlen(c->notes);
        char buf[512];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(buf, sizeof(buf), fmt, ap);
        va_end(ap);
        snprintf(c->notes + len, sizeof(c->notes) - len, "%s%s", len ? "; " : "", buf);
}

int fit_fail(struct fit_ctx *c, int r, const char *fmt, ...)
{
        va_list ap;

        pthread_mutex_lock(&c->lock);
        if (!c->error) {
                va_start(ap, fmt);
                vsnprintf(c->err, sizeof(c->err), fmt, ap);
                va_end(ap);
                c->error = r;
        }
        pthread_mutex_unlock(&c->lock);
        return r;
}

static bool opts_valid(const struct ap_fit_opts *o)
{
        return o && o->name && o->name[0] && o->name[0] != '.' && !strchr(o->name, '/') &&
               strlen(o->name) < AP_NAME_MAX && o->order >= 1 && o->order <= AP_ORDER_MAX &&
               o->k >= 1 && o->k <= AP_K_MAX && o->sample > 0 && o->sample <= 1 &&
               (o->reg == AP_REG_TIKHONOV || o->reg == AP_REG_TSVD) && o->tile >= 1 &&
               o->tile <= 64 && o->threads >= 1 && o->threads <= 16 && o->backends &&
               o->saturation > 0 && o->background >= 0;
}

/* ---- rows to views and lights ---- */

/* A lamp-lit image row and what groups it. */
struct rowkey {
        const struct ds_capture *r;
        int cam, lamp, bracket;
        long tt, ca, arm; /* millidegrees in [0, 360000), -1: no such axis */
};

static long mdeg(double a)
{
        return isnan(a) ? -1 : (long)llround(fmod(fmod(a, 360) + 360, 360) * 1000) % 360000;
}

static int cmp_key(const void *pa, const void *pb)
{
        const struct rowkey *a = pa, *b = pb;
        long d[] = {a->cam - b->cam, a->tt - b->tt,           a->ca - b->ca,      a->lamp - b->lamp,
                    a->arm - b->arm, a->bracket - b->bracket, a->r->id - b->r->id};

        for (size_t i = 0; i < sizeof(d) / sizeof(d[0]); i++)
                if (d[i])
                        return d[i] < 0 ? -1 : 1;
        return 0;
}

static int camera_index(const struct rig_config *rc, const char *name)
{
        for (size_t i = 0; i < rc->n_cameras; i++)
                if (strcmp(rc->cameras[i].name, name) == 0)
                        return (int)i;
        return -1;
}

/* The key of row r, false when it is no lamp-lit image of a rig camera. */
static bool key_of(const struct rig_config *rc, const struct ds_capture *r, struct rowkey *k)
{
        uint32_t l = r->pose.lamps;

        if ((strcmp(r->kind, "image") != 0 && r->kind[0]) || r->pose.lasers || !l || (l & (l - 1)))
                return false;
        *k = (struct rowkey){.r = r,
                             .cam = camera_index(rc, r->camera),
                             .lamp = __builtin_ctz(l),
                             .bracket = r->bracket,
                             .tt = mdeg(r->pose.deg[GN_ROLE_TURNTABLE]),
                             .ca = mdeg(r->pose.deg[GN_ROLE_CAMERA_ARM]),
                             .arm = mdeg(r->pose.deg[GN_ROLE_LIGHT_ARM])};
        return k->cam >= 0 && (size_t)k->lamp < rc->n_lamps;
}

static bool same_view(const struct rowkey *a, const struct rowkey *b)
{
        return a->cam == b->cam && a->tt == b->tt && a->ca == b->ca;
}

/* Fills view v from the sorted keys k[0 .. n) of one view. */
static int make_view(struct fit_view *v, const struct rowkey *k, size_t n)
{
        v->cam = k[0].cam;
        v->tt_deg = k[0].r->pose.deg[GN_ROLE_TURNTABLE];
        v->arm_deg = k[0].r->pose.deg[GN_ROLE_CAMERA_ARM];
        v->rows = malloc(n * sizeof(*v->rows));
        v->lights = calloc(n, sizeof(*v->lights));
        if (!v->rows || !v->lights)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++) {
                v->rows[v->n_rows++] = k[i].r;
                if (i == 0 || k[i].lamp != k[i - 1].lamp || k[i].arm != k[i - 1].arm)
                        v->lights[v->n_lights++] =
                                (struct fit_light){.lamp = k[i].lamp,
                                                   .arm_deg = k[i].r->pose.deg[GN_ROLE_LIGHT_ARM],
                                                   .first = i};
                v->lights[v->n_lights - 1].n++;
        }
        return 0;
}

/* Groups c->all's lamp-lit image rows into c->views; the reference exposure and gain. */
static int group_views(struct fit_ctx *c)
{
        _cleanup_free_ struct rowkey *k = malloc((c->n_all + 1) * sizeof(*k));
        size_t n = 0, skipped = 0;
        int r = 0;

        if (!k)
                return -ENOMEM;
        for (size_t i = 0; i < c->n_all; i++)
                if (key_of(c->rc, &c->all[i], &k[n]))
                        n++;
        if (n == 0)
                return fit_fail(c, -ENODATA, "no image rows with one lamp lit (%zu rows)",
                                c->n_all);
        qsort(k, n, sizeof(*k), cmp_key);
        c->views = calloc(n, sizeof(*c->views));
        if (!c->views)
                return -ENOMEM;
        for (size_t i = 0, j; r == 0 && i < n; i = j) {
                for (j = i + 1; j < n && same_view(&k[i], &k[j]);)
                        j++;
                r = make_view(&c->views[c->n_views++], k + i, j - i);
        }
        for (size_t i = 0; i < c->n_all; i++)
                skipped += strcmp(c->all[i].kind, "image") == 0 && !c->all[i].pose.lamps;
        if (skipped)
                fit_note(c, "%zu image rows without a lamp lit not used", skipped);
        c->exposure_ref = k[0].r->exposure_us > 0 ? k[0].r->exposure_us : 1;
        c->gain_ref = k[0].r->gain > 0 ? k[0].r->gain : 1;
        return r;
}

/* Views that have image rows but none lit by one lamp: stated as skipped. */
static int note_unlit_views(struct fit_ctx *c)
{
        _cleanup_free_ struct rowkey *k = malloc((c->n_all + 1) * sizeof(*k));
        size_t n = 0, skipped = 0;

        if (!k)
                return -ENOMEM;
        for (size_t i = 0; i < c->n_all; i++) {
                const struct ds_capture *r = &c->all[i];
                k[n] = (struct rowkey){.r = r,
                                       .cam = camera_index(c->rc, r->camera),
                                       .tt = mdeg(r->pose.deg[GN_ROLE_TURNTABLE]),
                                       .ca = mdeg(r->pose.deg[GN_ROLE_CAMERA_ARM])};
                n += strcmp(r->kind, "image") == 0 && k[n].cam >= 0;
        }
        qsort(k, n, sizeof(*k), cmp_key);
        for (size_t i = 0; i < n; i++) {
                bool seen = false;
                if (i > 0 && same_view(&k[i], &k[i - 1])) /* counted once: its first row */
                        continue;
                for (size_t v = 0; v < c->n_views && !seen; v++) {
                        struct rowkey w = {.cam = c->views[v].cam,
                                           .tt = mdeg(c->views[v].tt_deg),
                                           .ca = mdeg(c->views[v].arm_deg)};
                        seen = same_view(&k[i], &w);
                }
                skipped += !seen;
        }
        if (skipped)
                fit_note(c, "%zu views without a lamp-lit capture skipped", skipped);
        return 0;
}

/* Drops views with fewer than 4 lights, and lowers the order to what the fewest lights of a
 * view support, stating both. */
static int choose_order(struct fit_ctx *c)
{
        size_t kept = 0, fewest = SIZE_MAX;

        for (size_t i = 0; i < c->n_views; i++) {
                struct fit_view *v = &c->views[i];
                if (v->n_lights < 4) {
                        free(v->rows);
                        free(v->lights);
                        continue;
                }
                fewest = MIN(fewest, v->n_lights);
                c->views[kept++] = *v;
        }
        if (kept < c->n_views)
                fit_note(c, "%zu views with fewer than 4 lights skipped", c->n_views - kept);
        c->n_views = kept;
        if (kept == 0)
                return fit_fail(c, -ENODATA, "no view has 4 lights or more: nothing to fit");
        c->order = c->o->order;
        while ((size_t)c->order * c->order > fewest)
                c->order--;
        if (c->order < c->o->order)
                fit_note(c, "order %d needs %d lights per view, a view has %zu: order %d fitted",
                         c->o->order, c->o->order * c->o->order, fewest, c->order);
        c->M = c->order * c->order;
        return 0;
}

/* ---- the views on o->threads workers ---- */

/* The pilot views are solved first (their vectors kept for the PCA's sample), then the others
 * solved and projected, then the kept ones projected. The worker that solves the last pilot
 * fits the PCA meanwhile; a view solved before the basis is known is kept while views remain
 * to be solved, else its worker waits for the basis. */
struct run {
        struct fit_ctx *c;
        size_t next_pilot, next, next_kept; /* the next view of each stage */
        size_t pilots_left;                 /* pilot views not solved yet */
        bool basis;                         /* the PCA is fitted */
        int workers;                        /* started: the next one's slot in c->scratch */
        pthread_cond_t ready;               /* the basis, or an error */
};

/* Views other than pilots remain to be solved. Under c->lock. */
static bool unsolved_left(struct run *u)
{
        while (u->next < u->c->n_views && u->c->views[u->next].pilot)
                u->next++;
        return u->next < u->c->n_views;
}

/* Waits for the basis or an error (c->error). Under c->lock. */
static int wait_basis(struct run *u)
{
        while (!u->basis && !u->c->error)
                pthread_cond_wait(&u->ready, &u->c->lock);
        return u->c->error;
}

/* The next view to work on, *solve whether to solve it (else to project its kept vectors);
 * n_views: none left or an error. Under c->lock. */
static size_t next_view(struct run *u, bool *solve)
{
        struct fit_ctx *c = u->c;

        *solve = true;
        while (u->next_pilot < c->n_views && !c->views[u->next_pilot].pilot)
                u->next_pilot++;
        if (u->next_pilot < c->n_views)
                return u->next_pilot++;
        if (unsolved_left(u))
                return u->next++;
        *solve = false;
        if (wait_basis(u) < 0)
                return c->n_views;
        while (u->next_kept < c->n_views && !c->views[u->next_kept].kept)
                u->next_kept++;
        return u->next_kept < c->n_views ? u->next_kept++ : c->n_views;
}

/* View i solved into s: kept, or projected (once the basis is known); the PCA fitted after
 * the last pilot. */
static int after_solve(struct run *u, size_t i, struct fit_scratch *s)
{
        struct fit_ctx *c = u->c;
        bool pilot = c->views[i].pilot, keep, pca;
        int r = 0;

        pthread_mutex_lock(&c->lock);
        keep = pilot || (!u->basis && unsolved_left(u));
        if (keep)
                fit_view_keep(c, i, s);
        pca = pilot && --u->pilots_left == 0;
        pthread_mutex_unlock(&c->lock);
        if (pca && (r = fit_pca(c)) < 0)
                fit_fail(c, r, "the PCA failed: %zu sample vectors", c->n_sample);
        pthread_mutex_lock(&c->lock);
        u->basis |= pca && r == 0;
        pthread_cond_broadcast(&u->ready);
        if (r == 0 && !keep)
                r = wait_basis(u);
        pthread_mutex_unlock(&c->lock);
        return r < 0 || keep ? r : fit_view_project(c, i, s);
}

static void *run_worker(void *arg)
{
        struct run *u = arg;
        struct fit_ctx *c = u->c;
        struct fit_scratch **s;

        pthread_mutex_lock(&c->lock);
        s = &c->scratch[u->workers++];
        for (;;) {
                bool solve = false;
                size_t i = c->error ? c->n_views : next_view(u, &solve);
                int r;
                pthread_mutex_unlock(&c->lock);
                if (i >= c->n_views)
                        return NULL;
                r = solve ? fit_view_solve(c, i, s) : fit_view_project(c, i, NULL);
                if (r == 0 && solve)
                        r = after_solve(u, i, *s);
                if (r < 0) /* kept when a sentence came first */
                        fit_fail(c, r, "view %zu (%s): %s", i, c->rc->cameras[c->views[i].cam].name,
                                 strerror(-r));
                pthread_mutex_lock(&c->lock);
                if (c->error)
                        pthread_cond_broadcast(&u->ready);
        }
}

/* Fits, samples, fits the PCA on and projects every view, on o->threads threads. */
static int run_views(struct fit_ctx *c)
{
        struct run u = {.c = c};
        pthread_t t[16];
        int n = 0;

        for (size_t i = 0; i < c->n_views; i++)
                u.pilots_left += c->views[i].pilot;
        pthread_cond_init(&u.ready, NULL);
        while (n < c->o->threads - 1 && pthread_create(&t[n], NULL, run_worker, &u) == 0)
                n++;
        run_worker(&u);
        while (n > 0)
                pthread_join(t[--n], NULL);
        pthread_cond_destroy(&u.ready);
        return c->error;
}

/* Marks the pilot views and the sampling stride: about o->sample of every view's pixels,
 * at least MIN_SAMPLE_PER_DIM x 3M vectors from the pilots when they have them. */
static void choose_pilots(struct fit_ctx *c)
{
        size_t every = (c->n_views + AP_PILOT_EVERY - 1) / AP_PILOT_EVERY, all = 0, pilot = 0;

        for (size_t i = 0; i < c->n_views; i++) {
                size_t px = (size_t)c->views[i].geom.width * c->views[i].geom.height;
                c->views[i].pilot = i % every == 0;
                all += px;
                pilot += c->views[i].pilot ? px : 0;
        }
        c->stride = (size_t)fmax(1, floor(pilot / (c->o->sample * all)));
        c->stride = MIN(c->stride, MAX(1, pilot / (MIN_SAMPLE_PER_DIM * 3 * (size_t)c->M)));
}

/* ---- the model ---- */

/* The model's header and views (their weights come from run_views). */
static int model_new(struct fit_ctx *c)
{
        int k = MIN(c->o->k, 3 * c->M), r;

        if (k < c->o->k)
                fit_note(c, "%d components asked, %d coefficients: %d kept", c->o->k, 3 * c->M, k);
        r = ap_model_new(c->order, k, c->n_views, &c->model);
        if (r < 0)
                return r;
        for (size_t i = 0; i < c->n_views; i++) {
                struct ap_view *mv = &c->model->views[i];
                const struct fit_view *v = &c->views[i];
                snprintf(mv->camera, sizeof(mv->camera), "%s", c->rc->cameras[v->cam].name);
                mv->turntable_deg = v->tt_deg;
                mv->camera_arm_deg = v->arm_deg;
                mv->cam = v->geom;
                memcpy(mv->dir, v->dir, sizeof(mv->dir));
        }
        return 0;
}

/* The figures and the last notes into the model. */
static void model_finish(struct fit_ctx *c, double t0)
{
        struct ap_model *m = c->model;
        struct timespec ts;

        snprintf(m->name, sizeof(m->name), "%s", c->o->name);
        snprintf(m->reg, sizeof(m->reg), "%s", c->o->reg == AP_REG_TSVD ? "tsvd" : "tikhonov");
        m->reg_param = c->o->reg_param;
        m->light_distance_mm = c->d_ref;
        m->light_intensity = c->i_ref;
        m->rms_sh = c->n_sse ? sqrt(c->sse_sh / c->n_sse) : 0;
        if (c->cond_max > 1e3)
                fit_note(c,
                         "lights on part of the sphere only (condition number %.3g): "
                         "regularised, %s %g",
                         c->cond_max, m->reg, m->reg_param);
        if (c->masked_saturated)
                fit_note(c, "%zu pixels masked for a saturated sample", c->masked_saturated);
        snprintf(m->notes, sizeof(m->notes), "%s", c->notes);
        clock_gettime(CLOCK_MONOTONIC, &ts);
        m->fit_seconds = ts.tv_sec + ts.tv_nsec * 1e-9 - t0;
}

static void ctx_free(struct fit_ctx *c)
{
        for (size_t i = 0; c->views && i < c->n_views; i++) {
                free(c->views[i].rows);
                free(c->views[i].lights);
                free(c->views[i].points);
                free(c->views[i].kept);
                free(c->views[i].kept_pix);
        }
        for (size_t i = 0; i < sizeof(c->scratch) / sizeof(c->scratch[0]); i++)
                fit_scratch_free(c->scratch[i]);
        free(c->views);
        free(c->all);
        fit_mesh_free(&c->mesh);
        rigconf_free(c->rc);
        ap_model_free(c->model);
        pthread_mutex_destroy(&c->lock);
}

/* The rig file, the index rows and the views they group into. */
static int load_views(struct fit_ctx *c, struct ds *d)
{
        char path[4200], msg[512];
        int r;

        snprintf(path, sizeof(path), "%s/rig.yaml", c->dir);
        r = rigconf_load_stored(path, c->o->backends, &c->rc, msg, sizeof(msg));
        if (r < 0)
                return fit_fail(c, r, "%s", msg);
        if (c->rc->n_lamps == 0)
                return fit_fail(c, -ENODATA, "%s: the rig has no lamps: no appearance to fit",
                                path);
        r = ds_rows_collect(d, NULL, NULL, &c->all, &c->n_all);
        if (r < 0)
                return fit_fail(c, r, "reading the index: %s", ds_last_error(d));
        return group_views(c);
}

/* Everything but fitting the views: the rig, the rows, views, order, geometry, points, model. */
static int prepare(struct fit_ctx *c, struct ds *d)
{
        int r = load_views(c, d);

        if (r == 0)
                r = note_unlit_views(c);
        if (r == 0)
                r = choose_order(c);
        if (r == 0)
                r = fit_geometry(c);
        if (r == 0)
                r = fit_mesh_read(c);
        for (size_t i = 0; r == 0 && i < c->n_views; i++)
                r = fit_tile_points(c, &c->views[i]);
        if (r == 0)
                r = model_new(c);
        return r;
}

int ap_fit(struct ds *d, const struct ap_fit_opts *o, struct ap_model **ret, char *err,
           size_t errlen)
{
        struct ap_fit_opts opts = o ? *o : (struct ap_fit_opts){0};
        struct fit_ctx c = {.o = &opts};
        struct timespec ts;
        int r;

        if (!d || !ret || !opts_valid(o))
                return -EINVAL;
        clock_gettime(CLOCK_MONOTONIC, &ts);
        if (opts.reg_param < 0)
                opts.reg_param = ap_fit_reg_default(opts.reg);
        c.dir = ds_path(d);
        pthread_mutex_init(&c.lock, NULL);
        openblas_set_num_threads(1); /* the views run in parallel */
        r = prepare(&c, d);
        if (r == 0) {
                choose_pilots(&c);
                r = run_views(&c);
        }
        if (r == 0) {
                model_finish(&c, ts.tv_sec + ts.tv_nsec * 1e-9);
                *ret = TAKE_PTR(c.model);
        } else if (err) {
                snprintf(err, errlen, "%s", c.err[0] ? c.err : strerror(-r));
        }
        ctx_free(&c);
        return r;
}

/* Moves c's rig, rows, cameras and lights into g. */
static int take_geometry(struct fit_ctx *c, struct ap_geometry *g)
{
        size_t n = 0;

        for (size_t i = 0; i < c->n_views; i++)
                n += c->views[i].n_rows;
        g->cameras = calloc(c->n_views, sizeof(*g->cameras));
        g->shots = calloc(n, sizeof(*g->shots));
        if (!g->cameras || !g->shots)
                return -ENOMEM;
        for (size_t i = 0; i < c->n_views; i++) {
                const struct fit_view *v = &c->views[i];
                g->cameras[i] = v->geom;
                for (size_t k = 0; k < v->n_lights; k++)
                        for (size_t j = 0; j < v->lights[k].n; j++) {
                                const struct fit_light *l = &v->lights[k];
                                struct ap_shot *s = &g->shots[g->n_shots++];
                                *s = (struct ap_shot){.row = v->rows[l->first + j],
                                                      .view = i,
                                                      .cam = v->cam,
                                                      .intensity = l->scale * c->i_ref};
                                memcpy(s->lamp, l->pos, sizeof(s->lamp));
                        }
        }
        g->n_views = c->n_views;
        g->rc = TAKE_PTR(c->rc);
        g->rows = TAKE_PTR(c->all);
        g->n_rows = c->n_all;
        snprintf(g->notes, sizeof(g->notes), "%s", c->notes);
        return 0;
}

int ap_geometry_read(struct ds *d, const char *calibration,
                     const struct rig_backend *const *backends, struct ap_geometry **ret, char *err,
                     size_t errlen)
{
        struct ap_fit_opts o;
        struct fit_ctx c = {.o = &o};
        _cleanup_free_ struct ap_geometry *g = calloc(1, sizeof(*g));
        int r;

        if (!d || !ret)
                return -EINVAL;
        ap_fit_opts_default(&o);
        o.calibration = calibration;
        o.backends = backends;
        c.dir = ds_path(d);
        pthread_mutex_init(&c.lock, NULL);
        r = g ? load_views(&c, d) : -ENOMEM;
        if (r == 0)
                r = fit_geometry(&c);
        if (r == 0)
                r = take_geometry(&c, g);
        if (r == 0)
                *ret = TAKE_PTR(g);
        else if (err)
                snprintf(err, errlen, "%s", c.err[0] ? c.err : strerror(-r));
        ap_geometry_free(TAKE_PTR(g));
        ctx_free(&c);
        return r;
}

struct ap_geometry *ap_geometry_free(struct ap_geometry *g)
{
        if (g) {
                rigconf_free(g->rc);
                free(g->rows);
                free(g->cameras);
                free(g->shots);
                free(g);
        }
        return NULL;
}
