/* render.c - sim_render(): one frame of one camera, traced with Embree 16-ray packets on
 * every core, plus ground truth.
 *
 * DESIGN: the image is cut into 4x4-pixel tiles, one packet each, handed out to worker
 * threads by an atomic counter. A packet is traced, its hits resolved into surface points
 * (position, normals, tangent, material), lit by every lamp sample, the laser sheet and
 * the dome elements with one rtcOccluded16 per light, followed one bounce through
 * perfect mirrors, and written through the sensor model. Everything a worker needs is
 * on its stack; noise comes from a per-pixel counter hash, so the bytes do not depend on
 * the thread count or schedule. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "common/cleanup.h"
#include "common/clock.h"
#include "common/log.h"
#include "internal.h"

#define LANES       16
#define MAX_DEPTH   2
#define MAX_LIGHTS  (RIG_MAX_LAMPS * SIM_MAX_LAMP_SAMPLES)
#define MAX_THREADS 16
#define PACKET_MASK _Alignas(64) int /* Embree loads packet valid masks with aligned moves */

struct light_pt {
        struct v3 p;
        float intensity;
        int lamp;
};

struct emitter {
        struct v3 c;
        float r2, radiance;
};

/* A lit laser's sheet in the object frame: plane n.x = 0 through the axis, emitter o. */
struct laser_sheet {
        struct v3 n, o;
        float sigma, power; /* Gaussian half-width (mm), power */
        int ch;             /* colour channel */
};

struct fctx {
        const struct sim_scene *s;
        const struct rig_camera_conf *cc;
        const float *dirs;
        int cam, w, h, tiles_x, n_tiles;
        float M[9];  /* camera frame -> object frame */
        float Rw[9]; /* object frame -> world frame */
        struct v3 org;
        struct light_pt lights[MAX_LIGHTS];
        int n_lights;
        struct emitter emit[RIG_MAX_LAMPS];
        int n_emit;
        struct v3 *dome_dir; /* object frame */
        float *dome_w;       /* RGB */
        int n_dome;
        struct laser_sheet lz[RIG_MAX_LASERS]; /* the lit lasers */
        int n_lz;
        double escale;
        struct sensor_rt sensor;
        struct gn_frame *out;
        struct sim_truth *truth;
        atomic_int next;
};

/* Resolved surface points of one packet. */
struct hits {
        int on[LANES]; /* lane carries a surface point */
        struct v3 p[LANES], n[LANES], ng[LANES], t[LANES], v[LANES];
        struct surf sf[LANES];
        float L[LANES][3];
        uint32_t lamps[LANES];
};

static float eps_at(struct v3 p)
{
        return 2e-3f + 2e-6f * (fabsf(p.x) + fabsf(p.y) + fabsf(p.z));
}

static void ray_set(struct RTCRay16 *r, int i, struct v3 o, struct v3 d, float tfar)
{
        r->org_x[i] = o.x;
        r->org_y[i] = o.y;
        r->org_z[i] = o.z;
        r->dir_x[i] = d.x;
        r->dir_y[i] = d.y;
        r->dir_z[i] = d.z;
        r->tnear[i] = 0;
        r->tfar[i] = tfar;
        r->time[i] = 0;
        r->mask[i] = 0xffffffff;
        r->id[i] = i;
        r->flags[i] = 0;
}

/* An inactive lane: Embree may read every lane of a packet, so none stays undefined. */
static void ray_off(struct RTCRay16 *r, int i)
{
        ray_set(r, i, v3(0, 0, 0), v3(0, 0, 1), -INFINITY);
}

static void trace(const struct fctx *c, const int *valid, struct RTCRayHit16 *rh, bool coherent)
{
        struct RTCIntersectContext ic;

        rtcInitIntersectContext(&ic);
        ic.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                            : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
        for (int i = 0; i < LANES; i++) {
                rh->hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
                rh->hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, c->s->scn, &ic, rh);
}

/* Occlusion of a shadow packet; clears on[] for blocked lanes. */
static void occlude(const struct fctx *c, int *on, struct RTCRay16 *r)
{
        struct RTCIntersectContext ic;
        int any = 0;

        for (int i = 0; i < LANES; i++)
                any |= on[i];
        if (!any)
                return;
        rtcInitIntersectContext(&ic);
        rtcOccluded16(on, c->s->scn, &ic, r);
        for (int i = 0; i < LANES; i++)
                if (on[i] && r->tfar[i] == -INFINITY)
                        on[i] = 0;
}

static struct v3 local_pt(const struct rgeom *g, struct v3 p)
{
        const float *m = g->to_local;

        return v3(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3],
                  m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                  m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]);
}

static void uv_of(const struct rgeom *g, const struct RTCHit16 *h, int i, struct v3 pl, float uv[2])
{
        if (g->uvmap == UV_MESH) {
                const uint32_t *ix = g->mesh.idx + 3 * h->primID[i];
                float b1 = h->u[i], b2 = h->v[i], b0 = 1 - b1 - b2;
                for (int k = 0; k < 2; k++)
                        uv[k] = b0 * g->mesh.uv[2 * ix[0] + k] + b1 * g->mesh.uv[2 * ix[1] + k] +
                                b2 * g->mesh.uv[2 * ix[2] + k];
        } else if (g->uvmap == UV_SPHERE) {
                float r = g->uv_size / 2;
                uv[0] = atan2f(pl.y, pl.x) * (float)(0.5 * M_1_PI);
                uv[0] += uv[0] < 0 ? 1 : 0;
                uv[1] = 1 - acosf(CLAMP((pl.z - r) / r, -1.0f, 1.0f)) * (float)M_1_PI;
        } else {
                uv[0] = pl.x / g->uv_size + 0.5f;
                uv[1] = pl.y / g->uv_size + 0.5f;
        }
}

/* Shading normal of a hit (object frame, not yet oriented). */
static struct v3 shading_normal(const struct rgeom *g, const struct RTCHit16 *h, int i, struct v3 p,
                                struct v3 ng)
{
        if (g->kind == GEOM_SPHERE)
                return v3_norm(v3_sub(p, v3(g->centre[0], g->centre[1], g->centre[2])));
        if (!g->mesh.nrm)
                return ng;
        const uint32_t *ix = g->mesh.idx + 3 * h->primID[i];
        const float *n0 = g->mesh.nrm + 3 * ix[0], *n1 = g->mesh.nrm + 3 * ix[1];
        const float *n2 = g->mesh.nrm + 3 * ix[2];
        float b1 = h->u[i], b2 = h->v[i], b0 = 1 - b1 - b2;
        return v3_norm(v3(b0 * n0[0] + b1 * n1[0] + b2 * n2[0],
                          b0 * n0[1] + b1 * n1[1] + b2 * n2[1],
                          b0 * n0[2] + b1 * n1[2] + b2 * n2[2]));
}

/* Board-frame footprint of pixel (x, y): the neighbouring pixel rays cut the tangent plane. */
static void footprint(const struct fctx *c, const struct rgeom *g, int pix, struct v3 p,
                      struct v3 ng, float fp[4])
{
        int x = pix % c->w, y = pix / c->w;
        int nb[2] = {x + 1 < c->w ? pix + 1 : pix - 1, y + 1 < c->h ? pix + c->w : pix - c->w};
        float sign[2] = {x + 1 < c->w ? 1.0f : -1.0f, y + 1 < c->h ? 1.0f : -1.0f};
        float num = v3_dot(v3_sub(p, c->org), ng);

        for (int k = 0; k < 2; k++) {
                const float *d = c->dirs + 3 * nb[k];
                struct v3 dw = m3_mul(c->M, v3(d[0], d[1], d[2]));
                float den = v3_dot(dw, ng);
                struct v3 q = den != 0 ? v3_madd(c->org, dw, num / den) : p;
                struct v3 dl = v3_sub(local_pt(g, q), local_pt(g, p));
                fp[2 * k] = sign[k] * dl.x;
                fp[2 * k + 1] = sign[k] * dl.y;
        }
}

static void resolve_lane(const struct fctx *c, const struct RTCRayHit16 *rh, int i, int pix,
                         struct hits *h)
{
        const struct rgeom *g = &c->s->geoms[rh->hit.geomID[i]];
        struct v3 d = v3(rh->ray.dir_x[i], rh->ray.dir_y[i], rh->ray.dir_z[i]);
        struct v3 o = v3(rh->ray.org_x[i], rh->ray.org_y[i], rh->ray.org_z[i]);
        struct v3 p = v3_madd(o, d, rh->ray.tfar[i]);
        struct v3 ng = v3_norm(v3(rh->hit.Ng_x[i], rh->hit.Ng_y[i], rh->hit.Ng_z[i]));
        struct v3 n = shading_normal(g, &rh->hit, i, p, ng), ax, pl = p;
        const struct rmat *m = &c->s->mats[g->mat];
        float uv[2] = {0, 0};

        if (v3_dot(ng, d) > 0)
                ng = v3_scale(ng, -1);
        if (v3_dot(n, ng) < 0)
                n = v3_scale(n, -1);
        if (g->board || m->albedo_map || m->ks_map || m->alpha_map) {
                pl = local_pt(g, p);
                uv_of(g, &rh->hit, i, pl, uv);
        }
        surf_eval(m, uv[0], uv[1], &h->sf[i]);
        if (g->board) {
                float fp[4] = {0};
                bool back = v3_dot(d, v3(g->axis[0], g->axis[1], g->axis[2])) < 0;
                if (pix >= 0)
                        footprint(c, g, pix, p, ng, fp);
                float a = back ? g->board->white : board_albedo(g->board, pl.x, pl.y, fp);
                h->sf[i].albedo[0] = h->sf[i].albedo[1] = h->sf[i].albedo[2] = a;
        }
        ax = v3(g->axis[0], g->axis[1], g->axis[2]);
        h->t[i] = v3_madd(ax, n, -v3_dot(ax, n));
        if (v3_dot(h->t[i], h->t[i]) < 1e-8f)
                h->t[i] = v3_cross(n, fabsf(n.x) < 0.9f ? v3(1, 0, 0) : v3(0, 1, 0));
        h->t[i] = v3_norm(h->t[i]);
        h->p[i] = p;
        h->n[i] = n;
        h->ng[i] = ng;
        h->v[i] = v3_scale(d, -1);
        h->on[i] = -1;
}

/* Adds the light of irradiance e (RGB, on a plane facing l) from direction l to lane i. */
static void accumulate(struct hits *h, int i, struct v3 l, const float e[3])
{
        float f[3];

        brdf_cos(&h->sf[i], h->n[i], h->t[i], l, h->v[i], f);
        for (int k = 0; k < 3; k++)
                h->L[i][k] += f[k] * e[k];
}

static void shade_lamps(const struct fctx *c, struct hits *h)
{
        for (int k = 0; k < c->n_lights; k++) {
                const struct light_pt *lp = &c->lights[k];
                struct RTCRay16 r;
                PACKET_MASK on[LANES];
                float dist[LANES];

                for (int i = 0; i < LANES; i++) {
                        struct v3 l = v3_sub(lp->p, h->p[i]);
                        on[i] = 0;
                        if (!h->on[i] || v3_dot(l, h->ng[i]) <= 0 || v3_dot(l, h->n[i]) <= 0) {
                                ray_off(&r, i);
                                continue;
                        }
                        dist[i] = v3_len(l);
                        ray_set(&r, i, v3_madd(h->p[i], h->ng[i], eps_at(h->p[i])),
                                v3_scale(l, 1 / dist[i]), dist[i] * (1 - 1e-5f));
                        on[i] = -1;
                }
                occlude(c, on, &r);
                for (int i = 0; i < LANES; i++) {
                        if (!on[i])
                                continue;
                        struct v3 l = v3(r.dir_x[i], r.dir_y[i], r.dir_z[i]);
                        float e = lp->intensity / (dist[i] * dist[i]);
                        accumulate(h, i, l, (const float[3]){e, e, e});
                        h->lamps[i] |= 1u << lp->lamp;
                }
        }
}

/* Adds laser sheet lz's light to the hits of h. */
static void shade_laser(const struct fctx *c, const struct laser_sheet *lz, struct hits *h)
{
        struct RTCRay16 r;
        PACKET_MASK on[LANES];
        float dist[LANES], g[LANES];

        int any = 0;

        for (int i = 0; i < LANES; i++) /* most packets miss the sheet: test before filling */
                any |= h->on[i] && fabsf(v3_dot(lz->n, h->p[i])) <= 5 * lz->sigma;
        if (!any)
                return;
        for (int i = 0; i < LANES; i++) {
                float dp = h->on[i] ? v3_dot(lz->n, h->p[i]) : INFINITY;
                struct v3 l;
                on[i] = 0;
                ray_off(&r, i);
                if (fabsf(dp) > 5 * lz->sigma)
                        continue;
                l = v3_sub(lz->o, h->p[i]);
                if (v3_dot(l, h->ng[i]) <= 0)
                        continue;
                g[i] = expf(-dp * dp / (2 * lz->sigma * lz->sigma));
                dist[i] = v3_len(l);
                ray_set(&r, i, v3_madd(h->p[i], h->ng[i], eps_at(h->p[i])),
                        v3_scale(l, 1 / dist[i]), dist[i] * (1 - 1e-5f));
                on[i] = -1;
        }
        occlude(c, on, &r);
        for (int i = 0; i < LANES; i++)
                if (on[i]) {
                        float e[3] = {0, 0, 0};
                        e[lz->ch] = lz->power * g[i] / dist[i];
                        accumulate(h, i, v3(r.dir_x[i], r.dir_y[i], r.dir_z[i]), e);
                }
}

static void shade_dome(const struct fctx *c, struct hits *h)
{
        for (int k = 0; k < c->n_dome; k++) {
                struct v3 l = c->dome_dir[k];
                struct RTCRay16 r;
                PACKET_MASK on[LANES];

                for (int i = 0; i < LANES; i++) {
                        on[i] = 0;
                        if (!h->on[i] || v3_dot(l, h->ng[i]) <= 0 || v3_dot(l, h->n[i]) <= 0) {
                                ray_off(&r, i);
                                continue;
                        }
                        ray_set(&r, i, v3_madd(h->p[i], h->ng[i], eps_at(h->p[i])), l, INFINITY);
                        on[i] = -1;
                }
                occlude(c, on, &r);
                for (int i = 0; i < LANES; i++)
                        if (on[i])
                                accumulate(h, i, l, &c->dome_w[3 * k]);
        }
}

/* Radiance (RGB, into L) along a ray that leaves the scene: lamp spheres, then the dome. */
static void background(const struct fctx *c, struct v3 o, struct v3 d, float L[3])
{
        double wd[3], Ld[3];

        for (int k = 0; k < c->n_emit; k++) {
                struct v3 oc = v3_sub(c->emit[k].c, o);
                float b = v3_dot(oc, d);
                if (b > 0 && v3_dot(oc, oc) - b * b <= c->emit[k].r2) {
                        L[0] = L[1] = L[2] = c->emit[k].radiance;
                        return;
                }
        }
        if (c->s->dome.radiance <= 0)
                return;
        struct v3 w = m3_mul(c->Rw, d);
        wd[0] = w.x;
        wd[1] = w.y;
        wd[2] = w.z;
        dome_radiance(&c->s->dome, wd, Ld);
        for (int k = 0; k < 3; k++)
                L[k] = (float)Ld[k];
}

static void shade_packet(const struct fctx *c, struct RTCRayHit16 *rh, const int *valid,
                         const int *pix, int depth, struct hits *h);

/* One bounce through perfect mirrors: reflected packet, shaded recursively. */
static void shade_mirrors(const struct fctx *c, struct hits *h, int depth)
{
        struct RTCRayHit16 rh;
        struct hits h2;
        PACKET_MASK valid[LANES];
        int any = 0, nopix[LANES];
        float w[LANES];

        for (int i = 0; i < LANES; i++) {
                w[i] = h->on[i] && h->sf[i].model == SPEC_MIRROR
                               ? mirror_weight(&h->sf[i], v3_dot(h->n[i], h->v[i]))
                               : 0;
                valid[i] = w[i] > 0 && depth < MAX_DEPTH ? -1 : 0;
                nopix[i] = -1;
                if (!valid[i]) {
                        ray_off(&rh.ray, i);
                        continue;
                }
                struct v3 d = v3_madd(v3_scale(h->v[i], -1), h->n[i], 2 * v3_dot(h->n[i], h->v[i]));
                ray_set(&rh.ray, i, v3_madd(h->p[i], h->ng[i], eps_at(h->p[i])), d, INFINITY);
                any = 1;
        }
        if (!any)
                return;
        trace(c, valid, &rh, false);
        shade_packet(c, &rh, valid, nopix, depth + 1, &h2);
        for (int i = 0; i < LANES; i++)
                if (valid[i])
                        for (int k = 0; k < 3; k++)
                                h->L[i][k] += w[i] * h2.L[i][k];
}

static void shade_packet(const struct fctx *c, struct RTCRayHit16 *rh, const int *valid,
                         const int *pix, int depth, struct hits *h)
{
        for (int i = 0; i < LANES; i++) {
                h->on[i] = 0;
                h->lamps[i] = 0;
                h->L[i][0] = h->L[i][1] = h->L[i][2] = 0;
                if (!valid[i])
                        continue;
                if (rh->hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) {
                        struct v3 o = v3(rh->ray.org_x[i], rh->ray.org_y[i], rh->ray.org_z[i]);
                        background(c, o, v3(rh->ray.dir_x[i], rh->ray.dir_y[i], rh->ray.dir_z[i]),
                                   h->L[i]);
                        continue;
                }
                resolve_lane(c, rh, i, pix[i], h);
        }
        shade_lamps(c, h);
        for (int i = 0; i < c->n_lz; i++)
                shade_laser(c, &c->lz[i], h);
        if (c->n_dome)
                shade_dome(c, h);
        shade_mirrors(c, h, depth);
}

/* Electrons of each pixel of a packet as the sensor format samples them. */
static int packet_electrons(const struct fctx *c, const struct hits *h, const int *valid, int x0,
                            int y0, uint64_t *pix, float *e)
{
        enum sensor_format fmt = c->s->sensor.format;
        int n = 0, nch = fmt == FMT_RGB ? 3 : 1;

        for (int i = 0; i < LANES; i++) {
                int x = x0 + (i & 3), y = y0 + (i >> 2), ch = (y & 1) + (x & 1); /* RGGB */
                const float *L = h->L[i];
                if (!valid[i])
                        continue;
                pix[n] = (uint64_t)y * c->w + x;
                if (fmt == FMT_RGB)
                        for (int k = 0; k < 3; k++)
                                e[n * 3 + k] = L[k] * c->escale;
                else
                        e[n] = (fmt == FMT_MONO ? (L[0] + L[1] + L[2]) / 3 : L[ch]) * c->escale;
                n++;
        }
        return nch;
}

static void write_packet(const struct fctx *c, const struct hits *h, const int *valid, int x0,
                         int y0)
{
        uint64_t pix[LANES];
        float e[3 * LANES];
        uint16_t dn[3 * LANES];
        int nch = packet_electrons(c, h, valid, x0, y0, pix, e), n = 0;

        for (int i = 0; i < LANES; i++)
                n += valid[i] != 0;
        sensor_pixels(&c->sensor, pix, e, n, nch, dn);
        for (int i = 0, k = 0; i < LANES; i++) {
                int x = x0 + (i & 3), y = y0 + (i >> 2);
                uint8_t *row = c->out->data + (size_t)y * c->out->stride;
                if (!valid[i])
                        continue;
                for (int ch = 0; ch < nch; ch++) {
                        if (c->out->bits == 8)
                                row[x * nch + ch] = (uint8_t)dn[k * nch + ch];
                        else
                                ((uint16_t *)row)[x * nch + ch] = dn[k * nch + ch];
                }
                k++;
        }
}

static void write_truth(const struct fctx *c, int pix, const struct RTCRayHit16 *rh, int i,
                        const struct hits *h)
{
        struct sim_truth *t = c->truth;
        bool hit = h->on[i] != 0;
        struct v3 nw = hit ? m3_mul(c->Rw, h->n[i]) : v3(NAN, NAN, NAN);

        if (t->depth)
                t->depth[pix] = hit ? rh->ray.tfar[i] * c->dirs[3 * pix + 2] : NAN;
        if (t->normal) {
                t->normal[3 * pix] = nw.x;
                t->normal[3 * pix + 1] = nw.y;
                t->normal[3 * pix + 2] = nw.z;
        }
        if (t->point)
                for (int k = 0; k < 3; k++)
                        t->point[3 * pix + k] = hit ? (&h->p[i].x)[k] : NAN;
        if (t->lamp_mask)
                t->lamp_mask[pix] = hit ? h->lamps[i] : 0;
}

static void render_tile(const struct fctx *c, int tile)
{
        int x0 = (tile % c->tiles_x) * 4, y0 = (tile / c->tiles_x) * 4;
        struct RTCRayHit16 rh;
        struct hits h;
        PACKET_MASK valid[LANES];
        int pix[LANES];

        for (int i = 0; i < LANES; i++) {
                int x = x0 + (i & 3), y = y0 + (i >> 2);
                valid[i] = x < c->w && y < c->h ? -1 : 0;
                pix[i] = valid[i] ? y * c->w + x : 0;
                const float *d = c->dirs + 3 * pix[i];
                ray_set(&rh.ray, i, c->org, m3_mul(c->M, v3(d[0], d[1], d[2])), INFINITY);
        }
        trace(c, valid, &rh, true);
        shade_packet(c, &rh, valid, pix, 0, &h);
        write_packet(c, &h, valid, x0, y0);
        for (int i = 0; c->truth && i < LANES; i++)
                if (valid[i])
                        write_truth(c, pix[i], &rh, i, &h);
}

static void *worker(void *arg)
{
        struct fctx *c = arg;
        int t;

        while ((t = atomic_fetch_add(&c->next, 1)) < c->n_tiles)
                render_tile(c, t);
        return NULL;
}

static void run_workers(struct fctx *c, int n)
{
        pthread_t th[MAX_THREADS];
        int started = 0;

        for (int i = 1; i < MIN(n, MAX_THREADS); i++) {
                if (pthread_create(&th[started], NULL, worker, c) != 0)
                        break;
                started++;
        }
        worker(c);
        for (int i = 0; i < started; i++)
                pthread_join(th[i], NULL);
}

static void to_float9(const double d[9], float f[9])
{
        for (int i = 0; i < 9; i++)
                f[i] = (float)d[i];
}

/* Camera pose and the object-frame rotation of this frame. */
static void setup_camera(struct fctx *c, const struct gn_pose *st)
{
        double R[9], t[3], Rz[9], Rzi[9], Rt[9], M[9], C[3], Co[3];

        riggeom_camera_pose(c->cc, pose_deg(st, GN_ROLE_CAMERA_ARM), R, t);
        m3d_rot_z(pose_deg(st, GN_ROLE_TURNTABLE), Rz);
        m3d_rot_z(-pose_deg(st, GN_ROLE_TURNTABLE), Rzi);
        for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                        Rt[i * 3 + j] = R[j * 3 + i];
        m3d_mul(Rzi, Rt, M);
        m3d_apply(Rt, t, C);
        for (int i = 0; i < 3; i++)
                C[i] = -C[i];
        m3d_apply(Rzi, C, Co);
        to_float9(M, c->M);
        to_float9(Rz, c->Rw);
        c->org = v3((float)Co[0], (float)Co[1], (float)Co[2]);
}

static struct v3 to_obj(const double Rzi[9], const double p[3])
{
        double q[3];

        m3d_apply(Rzi, p, q);
        return v3((float)q[0], (float)q[1], (float)q[2]);
}

static void setup_lights(struct fctx *c, const struct gn_pose *st)
{
        const struct sim_scene *s = c->s;
        double Rzi[9], p[3], q[3];
        int ns = MAX(1, MIN(s->lamp_samples, SIM_MAX_LAMP_SAMPLES));

        m3d_rot_z(-pose_deg(st, GN_ROLE_TURNTABLE), Rzi);
        for (size_t l = 0; l < s->rc->n_lamps; l++) {
                if (!(st->lamps & (UINT32_C(1) << l)))
                        continue;
                riggeom_lamp_position(&s->rc->lamps[l], pose_deg(st, GN_ROLE_LIGHT_ARM), p);
                for (int k = 0; k < ns; k++) {
                        struct light_pt *lp = &c->lights[c->n_lights++];
                        lamp_sample(p, s->lamp_radius, k, ns, q);
                        lp->p = to_obj(Rzi, q);
                        lp->intensity = (float)(s->rc->lamps[l].intensity / ns);
                        lp->lamp = (int)l;
                }
                if (s->lamp_radius > 0) {
                        struct emitter *e = &c->emit[c->n_emit++];
                        e->c = to_obj(Rzi, p);
                        e->r2 = (float)(s->lamp_radius * s->lamp_radius);
                        e->radiance = (float)(s->rc->lamps[l].intensity /
                                              (M_PI * s->lamp_radius * s->lamp_radius));
                }
        }
}

/* The sheets of the lasers lit in st, in the object frame. */
static void setup_lasers(struct fctx *c, const struct gn_pose *st)
{
        double n[3], d, Rzi[9];

        m3d_rot_z(-pose_deg(st, GN_ROLE_TURNTABLE), Rzi);
        c->n_lz = 0;
        for (size_t i = 0; i < c->s->rc->n_lasers; i++) {
                const struct rig_switch_conf *lz = &c->s->rc->lasers[i];

                if (!(st->lasers & (UINT32_C(1) << i)) || sim_laser_plane(c->s, i, n, &d) < 0 ||
                    lz->laser_width_mm <= 0)
                        continue;
                c->lz[c->n_lz++] = (struct laser_sheet){.n = to_obj(Rzi, n),
                                                        .o = to_obj(Rzi, lz->laser_origin),
                                                        .sigma = (float)lz->laser_width_mm,
                                                        .power = (float)lz->laser_power,
                                                        .ch = CLAMP(lz->laser_channel, 0, 2)};
        }
}

static int setup_dome(struct fctx *c, const struct gn_pose *st)
{
        double Rzi[9];

        if (!c->s->n_dome)
                return 0;
        c->dome_dir = malloc(c->s->n_dome * sizeof(*c->dome_dir));
        c->dome_w = malloc(3 * c->s->n_dome * sizeof(*c->dome_w));
        if (!c->dome_dir || !c->dome_w)
                return -ENOMEM;
        m3d_rot_z(-pose_deg(st, GN_ROLE_TURNTABLE), Rzi);
        for (int k = 0; k < c->s->n_dome; k++) {
                c->dome_dir[k] = to_obj(Rzi, c->s->dome_els[k].dir);
                for (int ch = 0; ch < 3; ch++)
                        c->dome_w[3 * k + ch] = (float)c->s->dome_els[k].w[ch];
        }
        c->n_dome = c->s->n_dome;
        return 0;
}

static int alloc_truth(struct sim_truth *t, int w, int h, unsigned flags)
{
        size_t n = (size_t)w * h;

        memset(t, 0, sizeof(*t));
        t->width = w;
        t->height = h;
        if (((flags & SIM_TRUTH_DEPTH) && !(t->depth = malloc(n * sizeof(float)))) ||
            ((flags & SIM_TRUTH_NORMAL) && !(t->normal = malloc(3 * n * sizeof(float)))) ||
            ((flags & SIM_TRUTH_POINT) && !(t->point = malloc(3 * n * sizeof(float)))) ||
            ((flags & SIM_TRUTH_LAMP) && !(t->lamp_mask = malloc(n * sizeof(uint32_t))))) {
                sim_truth_free(t);
                return -ENOMEM;
        }
        return 0;
}

void sim_truth_free(struct sim_truth *t)
{
        if (!t)
                return;
        free(t->depth);
        free(t->normal);
        free(t->point);
        free(t->lamp_mask);
        t->depth = t->normal = t->point = NULL;
        t->lamp_mask = NULL;
}

static int setup_frame(struct fctx *c, const struct sim_expose *exp, uint64_t seq,
                       struct gn_frame *out)
{
        const struct rig_camera_conf *cc = c->cc;
        const struct sensor *se = &c->s->sensor;
        int exposure = exp && exp->exposure_us > 0 ? exp->exposure_us : cc->exposure_us;
        int bits = exp && exp->bits ? exp->bits : cc->bits ? cc->bits : 8;
        double gain = exp && exp->gain > 0 ? exp->gain : cc->gain > 0 ? cc->gain : 1;
        int r;

        if (bits != 8 && bits != 16)
                return -EINVAL;
        r = gn_frame_alloc(out, c->w, c->h, c->s->sensor.format == FMT_RGB ? 3 : 1, bits);
        if (r < 0)
                return r;
        out->timestamp_ns = gn_realtime_ns();
        out->exposure_us = exposure;
        out->gain = gain;
        out->seq = seq;
        c->escale = exposure * 1e-6 * se->response;
        sensor_setup(&c->sensor, se, c->s->noise_q,
                     sensor_frame_key(c->s->seed, seq, (uint32_t)c->cam), gain, bits,
                     exp && exp->no_noise);
        c->out = out;
        return 0;
}

int sim_render(struct sim_scene *s, const struct gn_pose *st, int cam, const struct sim_expose *exp,
               uint64_t seq, struct gn_frame *out, unsigned truth_flags, struct sim_truth *truth)
{
        _cleanup_free_ struct fctx *c = NULL;
        int r;

        if (!s || !st || !out || cam < 0 || (size_t)cam >= s->rc->n_cameras)
                return -EINVAL;
        c = calloc(1, sizeof(*c));
        if (!c)
                return -ENOMEM;
        c->s = s;
        c->cam = cam;
        c->cc = &s->rc->cameras[cam];
        c->dirs = s->cams[cam].dirs;
        c->w = c->cc->width;
        c->h = c->cc->height;
        c->tiles_x = (c->w + 3) / 4;
        c->n_tiles = c->tiles_x * ((c->h + 3) / 4);
        setup_camera(c, st);
        setup_lights(c, st);
        setup_lasers(c, st);
        r = setup_dome(c, st);
        if (r >= 0)
                r = setup_frame(c, exp, seq, out);
        if (r >= 0 && truth && truth_flags) {
                r = alloc_truth(truth, c->w, c->h, truth_flags);
                c->truth = r >= 0 ? truth : NULL;
        }
        if (r >= 0)
                run_workers(c, s->threads);
        if (r < 0 && out->data)
                gn_frame_free_data(out);
        free(c->dome_dir);
        free(c->dome_w);
        return r;
}
