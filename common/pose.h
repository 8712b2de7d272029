/* pose.h - the rig's state of one moment: the angle of each axis by its role, the
 * lit lamps and the lit lasers. One type for the rig, the dataset rows, the renderer's
 * state, and later the planner and the appearance fit, so that no tool matches axis
 * names as strings: an axis's role comes from the rig file (docs/rig-file.md). */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* What an axis moves. A rig has at most one axis of each role; any subset may exist. */
enum gn_role {
        GN_ROLE_TURNTABLE,  /* rotates the object about the world z axis */
        GN_ROLE_LIGHT_ARM,  /* rotates the lamps about the same axis */
        GN_ROLE_CAMERA_ARM, /* rotates the cameras about the same axis */
        GN_ROLE_COUNT,
};

/* Lamps and lasers are bit sets by rig-file index; this many fit. */
#define GN_POSE_MAX_LAMPS  32
#define GN_POSE_MAX_LASERS 32

struct gn_pose {
        double deg[GN_ROLE_COUNT]; /* NAN where the rig has no axis of that role */
        uint32_t lamps;            /* bit i set: lamp i (rig-file order) is lit */
        uint32_t lasers;           /* bit i set: laser i (rig-file order) is on */
};

/* The role's name as written in rig files, datasets and the protocol ("turntable",
 * "light_arm", "camera_arm"); NULL for an invalid role. */
const char *gn_role_name(enum gn_role role);

/* The role named name, or -ENOENT. */
int gn_role_from_name(const char *name);

/* A pose with no axis (all angles NAN), no lamp lit and every laser off. */
struct gn_pose gn_pose_none(void);

/* True when the rig has an axis of role in p (its angle is not NAN). */
bool gn_pose_has(const struct gn_pose *p, enum gn_role role);

/* True when a and b have the same axes within tol_deg (continuous angles compared modulo
 * 360), the same lamps and the same lasers. */
bool gn_pose_equal(const struct gn_pose *a, const struct gn_pose *b, double tol_deg);

/* Writes names[i] of each bit i set in bits, comma-separated in index order, into buf ("" for
 * none); n is the number of names. Returns the length, or -ENOBUFS when buf is too small (buf
 * then holds a truncated list). */
int gn_name_list(uint32_t bits, const char *const *names, size_t n, char *buf, size_t len);

/* Writes the names of the lit lamps of p, comma-separated in index order, into buf
 * ("" for none); names[i] is lamp i's name, n the number of lamps. Returns the length, or
 * -ENOBUFS when buf is too small (buf then holds a truncated list). */
int gn_pose_lamp_list(const struct gn_pose *p, const char *const *names, size_t n, char *buf,
                      size_t len);

/* Distance of two angles in degrees on the circle, in [0, 180]. */
double gn_angle_distance(double a, double b);
