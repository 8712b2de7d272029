/* proto.c - pure encoding and decoding of G-code controller lines (Horus 0.2, GRBL 1.1). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "drivers/axis/gcode/proto.h"

#define GREETING_TAIL " ['$' for help]"

const char *gc_flavor_name(enum gc_flavor f)
{
        return f == GC_FLAVOR_GRBL ? "grbl" : "horus";
}

static bool starts(const char *s, const char *prefix)
{
        return strncmp(s, prefix, strlen(prefix)) == 0;
}

/* The machine state named at s (up to ',' '|' or '>'). */
static enum gc_state parse_state(const char *s)
{
        static const struct {
                const char *name;
                enum gc_state st;
        } states[] = {
                {"Idle", GC_ST_IDLE}, {"Run", GC_ST_RUN},     {"Queue", GC_ST_RUN},
                {"Jog", GC_ST_RUN},   {"Hold:0", GC_ST_HELD}, {"Hold:1", GC_ST_HOLD},
                {"Hold", GC_ST_HOLD}, {"Home", GC_ST_HOME},   {"Alarm", GC_ST_ALARM},
        };
        size_t n = strcspn(s, ",|>");

        for (size_t i = 0; i < ELEMENTSOF(states); i++)
                if (strlen(states[i].name) == n && strncmp(s, states[i].name, n) == 0)
                        return states[i].st;
        return GC_ST_OTHER;
}

/* "<State,MPos:x,y,z,...>" (0.9) or "<State|MPos:x,y,z|...>" (1.1). */
static int parse_status(const char *line, struct gc_status *st)
{
        const char *p;
        char *end;

        if (line[strlen(line) - 1] != '>')
                return -EPROTO;
        st->state = parse_state(line + 1);
        p = strstr(line, "MPos:");
        if (!p)
                return -EPROTO;
        p += strlen("MPos:");
        for (int i = 0; i < GC_N_AXES; i++) {
                st->mpos[i] = strtod(p, &end);
                if (end == p || !isfinite(st->mpos[i]))
                        return -EPROTO;
                p = end + (*end == ',');
        }
        return 0;
}

/* "error:N", "error: Text", "ALARM:N", "ALARM: Text": the code or the text after the colon. */
static void parse_coded(const char *rest, struct gc_line *ret)
{
        char *end;

        while (*rest == ' ')
                rest++;
        ret->text = rest;
        if (isdigit((unsigned char)*rest)) {
                long v = strtol(rest, &end, 10);
                if (*end == '\0' && v < 1000)
                        ret->code = (int)v;
        }
}

/* "[MSG:text]" (1.1) or "[text]" (0.9). */
static void parse_msg(const char *line, struct gc_line *ret)
{
        const char *t = line + 1 + (starts(line + 1, "MSG:") ? 4 : 0);
        size_t n = strlen(t) - 1; /* without ']' */

        ret->kind = GC_LINE_MSG;
        ret->text = t;
        ret->alarm_lock = n == strlen("'$H'|'$X' to unlock") && starts(t, "'$H'|'$X' to unlock");
        ret->unlocked = n == strlen("Caution: Unlocked") && starts(t, "Caution: Unlocked");
}

static bool is_greeting(const char *line, struct gc_line *ret)
{
        size_t n = strlen(line), tail = strlen(GREETING_TAIL);

        if (n <= tail || strcmp(line + n - tail, GREETING_TAIL) != 0)
                return false;
        if (starts(line, "Grbl "))
                ret->flavor = GC_FLAVOR_GRBL;
        else if (starts(line, "Horus "))
                ret->flavor = GC_FLAVOR_HORUS;
        else
                return false;
        return true;
}

int gc_parse_line(const char *line, struct gc_line *ret)
{
        size_t n = strlen(line);

        *ret = (struct gc_line){.kind = GC_LINE_OTHER, .text = ""};
        if (n == 0)
                ret->kind = GC_LINE_EMPTY;
        else if (strcmp(line, "ok") == 0)
                ret->kind = GC_LINE_OK;
        else if (starts(line, "error:")) {
                ret->kind = GC_LINE_ERROR;
                parse_coded(line + strlen("error:"), ret);
        } else if (starts(line, "ALARM:")) {
                ret->kind = GC_LINE_ALARM;
                parse_coded(line + strlen("ALARM:"), ret);
        } else if (line[0] == '<') {
                ret->kind = GC_LINE_STATUS;
                return parse_status(line, &ret->status);
        } else if (line[0] == '[' && line[n - 1] == ']')
                parse_msg(line, ret);
        else if (is_greeting(line, ret))
                ret->kind = GC_LINE_GREETING;
        return 0;
}

int gc_format_move(char *buf, size_t len, int axis, double deg, double feed_deg_min)
{
        static const char letters[GC_N_AXES] = {'X', 'Y', 'Z'};
        int n;

        if (axis < 0 || axis >= GC_N_AXES || !isfinite(deg) || fabs(deg) > 1e6 ||
            !(feed_deg_min > 0) || feed_deg_min > 1e7)
                return -ERANGE;
        n = snprintf(buf, len, "G1 %c%.3f F%.0f", letters[axis], deg == 0 ? 0.0 : deg,
                     feed_deg_min);
        return n < 0 || (size_t)n >= len ? -ENOBUFS : n;
}

double gc_wrap(double deg)
{
        double w = fmod(deg, 360.0);

        if (w < 0)
                w += 360.0;
        return w >= 360.0 ? 0.0 : w;
}

int gcax_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "flavor", "axis", "steps_per_deg", NULL};
        char flavor[16] = "horus", axis[4] = "X";
        struct gcax_conf *c = conf;
        double spd = GC_STEPS_PER_DEG_DEFAULT;
        int r;

        (void)rc;
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_str(yc, m, "flavor", flavor, sizeof(flavor))) < 0 ||
            (r = yconf_str(yc, m, "axis", axis, sizeof(axis))) < 0 ||
            (r = yconf_double(yc, m, "steps_per_deg", 1e-3, 1e5, &spd)) < 0)
                return r;
        if (strcmp(flavor, "horus") != 0 && strcmp(flavor, "grbl") != 0)
                return yconf_error(yc, yconf_get(m, "flavor"), "flavor",
                                   "'%s' is no G-code flavor (horus, grbl)", flavor);
        if (strlen(axis) != 1 || !strchr("XYZ", axis[0]))
                return yconf_error(yc, yconf_get(m, "axis"), "axis", "'%s' is not X, Y or Z", axis);
        *c = (struct gcax_conf){
                .flavor = strcmp(flavor, "grbl") == 0 ? GC_FLAVOR_GRBL : GC_FLAVOR_HORUS,
                .axis = axis[0] - 'X',
                .steps_per_deg = spd,
        };
        *addr = (struct rig_addr){.key = "axis", .value = c->axis};
        return 0;
}
