/* pose.c - the rig's state of one moment (see pose.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "pose.h"

static const char *const role_names[GN_ROLE_COUNT] = {
        [GN_ROLE_TURNTABLE] = "turntable",
        [GN_ROLE_LIGHT_ARM] = "light_arm",
        [GN_ROLE_CAMERA_ARM] = "camera_arm",
};

const char *gn_role_name(enum gn_role role)
{
        return (unsigned)role < GN_ROLE_COUNT ? role_names[role] : NULL;
}

int gn_role_from_name(const char *name)
{
        for (int i = 0; i < GN_ROLE_COUNT; i++)
                if (name && strcmp(name, role_names[i]) == 0)
                        return i;
        return -ENOENT;
}

struct gn_pose gn_pose_none(void)
{
        struct gn_pose p = {0};

        for (int i = 0; i < GN_ROLE_COUNT; i++)
                p.deg[i] = NAN;
        return p;
}

bool gn_pose_has(const struct gn_pose *p, enum gn_role role)
{
        return (unsigned)role < GN_ROLE_COUNT && !isnan(p->deg[role]);
}

double gn_angle_distance(double a, double b)
{
        double d = fmod(fabs(a - b), 360.0);

        return d > 180 ? 360 - d : d;
}

bool gn_pose_equal(const struct gn_pose *a, const struct gn_pose *b, double tol_deg)
{
        if (a->lamps != b->lamps || a->lasers != b->lasers)
                return false;
        for (int i = 0; i < GN_ROLE_COUNT; i++) {
                if (isnan(a->deg[i]) != isnan(b->deg[i]))
                        return false;
                if (!isnan(a->deg[i]) && gn_angle_distance(a->deg[i], b->deg[i]) > tol_deg)
                        return false;
        }
        return true;
}

int gn_name_list(uint32_t bits, const char *const *names, size_t n, char *buf, size_t len)
{
        size_t used = 0;

        if (len == 0)
                return -ENOBUFS;
        buf[0] = 0;
        for (size_t i = 0; i < n && i < sizeof(bits) * 8; i++) {
                int w;

                if (!(bits & (UINT32_C(1) << i)))
                        continue;
                w = snprintf(buf + used, len - used, "%s%s", used ? "," : "", names[i]);
                if (w < 0 || (size_t)w >= len - used)
                        return -ENOBUFS;
                used += w;
        }
        return (int)used;
}

int gn_pose_lamp_list(const struct gn_pose *p, const char *const *names, size_t n, char *buf,
                      size_t len)
{
        return gn_name_list(p->lamps, names, n, buf, len);
}
