/* proto.c - the pure parts of the "gpio-stepper" axis backend: its rig-file map, the trapezoidal
 * step schedule and the conversions between degrees and steps. */
#include <errno.h>
#include <libfyaml.h>
#include <math.h>
#include <string.h>

#include "drivers/axis/gpio/proto.h"

/* Positions beyond this many steps lose integer precision as doubles. */
#define STEPS_MAX 9007199254740992.0 /* 2^53 */

const char *const gpst_line_keys[GPST_N_LINES] = {"step", "dir",       "enable",
                                                  "home", "limit_min", "limit_max"};

/* The line role named name, or -1. */
static int line_of(const char *name)
{
        for (int i = 0; i < GPST_N_LINES; i++)
                if (name && strcmp(name, gpst_line_keys[i]) == 0)
                        return i;
        return -1;
}

/* Reads "active_low: [enable, home]": roles whose lines are active low. */
static int parse_active_low(struct yconf *yc, struct fy_node *m, struct gpst_conf *c)
{
        struct fy_node *seq = yconf_get(m, "active_low");
        int n;

        if (!seq)
                return 0;
        n = yconf_seq_len(yc, seq, "active_low");
        for (int i = 0; i < n; i++) {
                struct fy_node *item = yconf_seq_item(seq, i);
                const char *name =
                        fy_node_get_type(item) == FYNT_SCALAR ? fy_node_get_scalar0(item) : NULL;
                int l = line_of(name);

                if (l < 0)
                        return yconf_error(yc, item, "active_low",
                                           "'%s' is not a line of the axis (step, dir, enable, "
                                           "home, limit_min, limit_max)",
                                           name ? name : "?");
                c->active_low[l] = true;
        }
        return n < 0 ? n : 0;
}

/* Reads the line keys; step and dir are required, and no line may serve two roles. */
static int parse_lines(struct yconf *yc, struct fy_node *m, struct gpst_conf *c)
{
        int r;

        for (int i = 0; i < GPST_N_LINES; i++) {
                r = i <= GPST_DIR
                            ? yconf_str_req(yc, m, gpst_line_keys[i], c->lines[i],
                                            sizeof(c->lines[i]))
                            : yconf_str(yc, m, gpst_line_keys[i], c->lines[i], sizeof(c->lines[i]));
                if (r < 0)
                        return r;
                for (int j = 0; j < i && c->lines[i][0]; j++)
                        if (strcmp(c->lines[i], c->lines[j]) == 0)
                                return yconf_error(yc, yconf_get(m, gpst_line_keys[i]),
                                                   gpst_line_keys[i], "line %s is also '%s'",
                                                   c->lines[i], gpst_line_keys[j]);
        }
        return 0;
}

int gpst_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus",        "chip",          "step",      "dir",
                                           "enable",     "home",          "limit_min", "limit_max",
                                           "active_low", "steps_per_deg", "home_dir",  "home_speed",
                                           NULL};
        struct gpst_conf *c = conf;
        long home_dir = -1;
        int r;

        *c = (struct gpst_conf){};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_str_req(yc, m, "chip", c->chip, sizeof(c->chip))) < 0 ||
            (r = parse_lines(yc, m, c)) < 0 || (r = parse_active_low(yc, m, c)) < 0 ||
            (r = yconf_double(yc, m, "steps_per_deg", 1e-3, 1e7, &c->steps_per_deg)) < 0 ||
            (r = yconf_int(yc, m, "home_dir", -1, 1, &home_dir)) < 0 ||
            (r = yconf_double(yc, m, "home_speed", 0, 1e4, &c->home_speed)) < 0)
                return r;
        if (!yconf_get(m, "steps_per_deg"))
                return yconf_error(yc, m, "steps_per_deg", "required key is missing");
        if (home_dir == 0)
                return yconf_error(yc, yconf_get(m, "home_dir"), "home_dir", "must be -1 or 1");
        c->home_dir = (int)home_dir;
        *addr = (struct rig_addr){};
        return 0;
}

int gpst_profile_init(struct gpst_profile *p, long n, double v, double a)
{
        if (!(v > 0) || isinf(v) || n < 0)
                return -EINVAL;
        *p = (struct gpst_profile){.n = n, .v = v, .a = a};
        if (!(a > 0)) {
                p->total = n / v;
                return 0;
        }
        p->ramp_steps = v * v / (2.0 * a);
        if (2.0 * p->ramp_steps >= n) { /* triangular: never reaches v */
                p->ramp_steps = n / 2.0;
                p->t_ramp = sqrt(n / a);
                p->total = 2.0 * p->t_ramp;
        } else {
                p->t_ramp = v / a;
                p->total = n / v + v / a;
        }
        return 0;
}

double gpst_step_time(const struct gpst_profile *p, long k)
{
        double s = (double)k;

        if (p->t_ramp == 0)
                return s / p->v;
        if (s <= p->ramp_steps)
                return sqrt(2.0 * s / p->a);
        if (s >= p->n - p->ramp_steps)
                return p->total - sqrt(2.0 * fmax(p->n - s, 0.0) / p->a);
        return p->t_ramp + (s - p->ramp_steps) / p->v;
}

int gpst_deg_to_steps(double steps_per_deg, double deg, int64_t *ret)
{
        double s = round(deg * steps_per_deg);

        if (!isfinite(s) || fabs(s) > STEPS_MAX)
                return -ERANGE;
        *ret = (int64_t)s;
        return 0;
}

double gpst_steps_to_deg(double steps_per_deg, int64_t steps, bool continuous)
{
        double deg = (double)steps / steps_per_deg;

        if (!continuous)
                return deg;
        deg = fmod(deg, 360.0);
        if (deg < 0)
                deg += 360.0;
        return deg >= 360.0 ? 0.0 : deg;
}

int gpst_travel_steps(double steps_per_deg, int64_t cur, double delta_deg, int64_t *ret)
{
        int64_t d;
        int r = gpst_deg_to_steps(steps_per_deg, delta_deg, &d);

        if (r < 0)
                return r;
        *ret = cur + d;
        return 0;
}
