/* plan.c - bench/plan: the paper's capture (20 turntable x 20 light-arm positions x 5 cameras
 * x 8 lamps, examples/sessions/paper.yaml on examples/rigs/paper.yaml) planned on the rig's
 * timing model, against the lower bound (unavoidable motion and exposure, docs/sessions.md)
 * and against the naive nested-loop order (plan_build_naive()). Targets: within 5% of the
 * bound, at least 2x faster than naive. Prints human lines, then one JSON line.
 * Usage: plan [RIG SESSION] (default: the examples of the source tree). */
#include <stdio.h>
#include <time.h>

#include "bench/clock.h"
#include "common/rigconf.h"
#include "common/sessconf.h"
#include "daemon/plan.h"
#include "drivers/registry.h"

static void describe(const char *what, const struct plan *p)
{
        printf("%-8s %6zu captures in %5zu shots, %4zu moves, order", what, p->n_captures,
               p->n_shots, p->n_moves);
        for (int i = 0; i < p->n_order; i++)
                printf(" %s", gn_role_name(p->order[i]));
        printf(": %8.1f s (%.2f h)\n", p->estimate_s, p->estimate_s / 3600);
}

/* Counts the skips: lamps hidden (every camera) and lamps glaring into one camera. */
static void skips(const struct plan *p)
{
        size_t hidden = 0, glare = 0;

        for (size_t i = 0; i < p->n_skips; i++)
                p->skips[i].camera < 0 ? hidden++ : glare++;
        printf("skipped: %zu lamps hidden behind a camera (no camera's image), %zu images of a "
               "lamp shining into the camera\n",
               hidden, glare);
        for (size_t i = 0; i < p->n_skips && i < 3; i++)
                printf("  e.g. %s at turntable %g, light arm %g\n", p->skips[i].reason,
                       p->skips[i].pose.deg[GN_ROLE_TURNTABLE],
                       p->skips[i].pose.deg[GN_ROLE_LIGHT_ARM]);
}

int main(int argc, char **argv)
{
        const char *rig = argc > 2 ? argv[1] : GONIO_SOURCE_ROOT "/examples/rigs/paper.yaml";
        const char *sess = argc > 2 ? argv[2] : GONIO_SOURCE_ROOT "/examples/sessions/paper.yaml";
        struct rig_config *rc = NULL;
        struct session_conf *sc = NULL;
        struct plan *p = NULL, *naive = NULL;
        char err[512];
        double t0, t_plan;

        if (rigconf_load(rig, registry_backends, &rc, err, sizeof(err)) < 0 ||
            sessconf_load(sess, rc, &sc, err, sizeof(err)) < 0) {
                fprintf(stderr, "%s\n", err);
                return 1;
        }
        t0 = bench_wall_s();
        if (plan_build(rc, sc, NULL, &p) < 0 || plan_build_naive(rc, sc, NULL, &naive) < 0) {
                fprintf(stderr, "planning failed\n");
                return 1;
        }
        t_plan = bench_wall_s() - t0;
        printf("session '%s' on rig '%s': planned in %.0f ms\n", sc->name, rc->name, t_plan * 1e3);
        skips(p);
        describe("planned", p);
        describe("naive", naive);
        printf("lower bound %.1f s: planned is %.3f of it; naive takes %.2fx the planned time\n",
               p->lower_bound_s, p->estimate_s / p->lower_bound_s,
               naive->estimate_s / p->estimate_s);
        printf("{\"bench\":\"plan\",\"planned_s\":%.1f,\"lower_bound_s\":%.1f,\"naive_s\":%.1f,"
               "\"captures\":%zu,\"skipped\":%zu}\n",
               p->estimate_s, p->lower_bound_s, naive->estimate_s, p->n_captures, p->n_skips);
        plan_free(p);
        plan_free(naive);
        sessconf_free(sc);
        rigconf_free(rc);
        return 0;
}
