/* light.c - lamps on the light arm (positions, area samples), the laser plane and the
 * dome (room / sky) light split adaptively into point lights at infinity, after Takada et
 * al. (seed 004): a patch is split while it carries more than a threshold of the energy.
 * The dome is procedural or a lat-long environment map; either way only its radiance matters. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "common/cleanup.h"
#include "internal.h"

void lamp_sample(const double p[3], double r, int k, int n, double out[3])
{
        double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        double w[3], u[3], v[3], rho, phi;

        for (int i = 0; i < 3; i++)
                out[i] = p[i];
        if (n <= 1 || r <= 0 || len <= 0)
                return;
        for (int i = 0; i < 3; i++)
                w[i] = p[i] / len;
        /* u: horizontal, perpendicular to w (or x when w is vertical) */
        u[0] = -w[1];
        u[1] = w[0];
        u[2] = 0;
        double ul = hypot(u[0], u[1]);
        if (ul < 1e-9) {
                u[0] = 1;
                u[1] = 0;
                ul = 1;
        }
        u[0] /= ul;
        u[1] /= ul;
        v[0] = w[1] * u[2] - w[2] * u[1];
        v[1] = w[2] * u[0] - w[0] * u[2];
        v[2] = w[0] * u[1] - w[1] * u[0];
        /* Vogel spiral: equal-area, deterministic */
        rho = r * sqrt((k + 0.5) / n);
        phi = k * M_PI * (3 - sqrt(5.0));
        for (int i = 0; i < 3; i++)
                out[i] += rho * (cos(phi) * u[i] + sin(phi) * v[i]);
}

int sim_lamp_position(const struct sim_scene *s, const struct gn_pose *st, int lamp, double out[3])
{
        if (!s || !st || !out || lamp < 0 || (size_t)lamp >= s->rc->n_lamps)
                return -EINVAL;
        riggeom_lamp_position(&s->rc->lamps[lamp], pose_deg(st, GN_ROLE_LIGHT_ARM), out);
        return 0;
}

int sim_laser_plane(const struct sim_scene *s, int laser, double n[3], double *d)
{
        double phi;

        if (!s || laser < 0 || (size_t)laser >= s->rc->n_lasers)
                return -ENOENT;
        phi = s->rc->lasers[laser].laser_azimuth_deg * M_PI / 180;
        n[0] = -sin(phi);
        n[1] = cos(phi);
        n[2] = 0;
        *d = 0;
        return 0;
}

void dome_radiance(const struct dome *d, const double w[3], double out[3])
{
        double L = w[2] < 0 ? d->ground : 1 + (d->zenith_ratio - 1) * w[2];
        float px[3] = {1, 1, 1};

        if (d->env) { /* lat-long, row 0 at the zenith (appearance/envmap.h) */
                double phi = atan2(w[1], w[0]), th = acos(CLAMP(w[2], -1.0, 1.0));
                rtex_sample(d->env, (float)(phi * 0.5 * M_1_PI + (phi < 0)),
                            (float)CLAMP(1 - th * M_1_PI, 0.5 / d->env->h, 1 - 0.5 / d->env->h),
                            px);
                L = 1;
        }
        for (int c = 0; c < 3; c++)
                out[c] = d->radiance * L * px[c];
}

struct patch {
        double t0, t1, p0, p1; /* polar angle from zenith, azimuth */
        double e[3];           /* radiance x solid angle, RGB */
        double energy;         /* their mean: what the split compares */
};

static void dir_of(double th, double ph, double w[3])
{
        w[0] = sin(th) * cos(ph);
        w[1] = sin(th) * sin(ph);
        w[2] = cos(th);
}

/* Quadrature points per side of a patch: 3, or about one per texel of the map. */
static int patch_steps(const struct dome *d, const struct patch *p)
{
        if (!d->env)
                return 3;
        return CLAMP((int)ceil((p->t1 - p->t0) * d->env->h * M_1_PI), 3, 64);
}

/* Energy (radiance x solid angle) of a patch by midpoint quadrature. */
static void patch_energy(const struct dome *d, struct patch *p)
{
        int n = patch_steps(d, p);
        double dt = (p->t1 - p->t0) / n, dp = (p->p1 - p->p0) / n;

        p->e[0] = p->e[1] = p->e[2] = 0;
        for (int i = 0; i < n; i++)
                for (int j = 0; j < n; j++) {
                        double w[3], L[3], th = p->t0 + (i + 0.5) * dt;

                        dir_of(th, p->p0 + (j + 0.5) * dp, w);
                        dome_radiance(d, w, L);
                        for (int c = 0; c < 3; c++)
                                p->e[c] += L[c] * sin(th) * dt * dp;
                }
        p->energy = (p->e[0] + p->e[1] + p->e[2]) / 3;
}

static void split(const struct dome *d, struct patch *ps, int i, int *n)
{
        struct patch p = ps[i];
        double tm = (p.t0 + p.t1) / 2, pm = (p.p0 + p.p1) / 2;
        struct patch q[4] = {
                {p.t0, tm, p.p0, pm, {0}, 0},
                {p.t0, tm, pm, p.p1, {0}, 0},
                {tm, p.t1, p.p0, pm, {0}, 0},
                {tm, p.t1, pm, p.p1, {0}, 0},
        };

        for (int k = 0; k < 4; k++) {
                patch_energy(d, &q[k]);
                if (k == 0)
                        ps[i] = q[k];
                else
                        ps[(*n)++] = q[k];
        }
}

int dome_build(const struct dome *d, struct dome_el **ret, int *n_ret)
{
        int rows = d->ground > 0 || d->env ? 4 : 2, n = 0, cap = MAX(d->max_elements, 8 * rows);
        _cleanup_free_ struct patch *ps = calloc(cap + 4, sizeof(*ps));
        double total = 0;
        struct dome_el *els;

        if (!ps)
                return -ENOMEM;
        for (int i = 0; i < rows; i++)
                for (int j = 0; j < 8; j++) {
                        struct patch p = {i * M_PI / 4, (i + 1) * M_PI / 4,
                                          j * M_PI / 4, (j + 1) * M_PI / 4,
                                          {0},          0};
                        patch_energy(d, &p);
                        total += p.energy;
                        ps[n++] = p;
                }
        while (n + 3 <= cap) {
                int best = 0;
                for (int i = 1; i < n; i++)
                        if (ps[i].energy > ps[best].energy)
                                best = i;
                if (ps[best].energy <= d->threshold * total)
                        break;
                split(d, ps, best, &n);
        }
        els = calloc(n, sizeof(*els));
        if (!els)
                return -ENOMEM;
        for (int i = 0; i < n; i++) {
                dir_of((ps[i].t0 + ps[i].t1) / 2, (ps[i].p0 + ps[i].p1) / 2, els[i].dir);
                for (int c = 0; c < 3; c++)
                        els[i].w[c] = ps[i].e[c];
        }
        *ret = els;
        *n_ret = n;
        return 0;
}
