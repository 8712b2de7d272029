/* riggeom.h - the rig's geometry from the rig file: where the lamps and the cameras are
 * for given arm angles, how the cameras look, and light directions in the object's frame.
 * Shared by the planner (occlusion and glare), the simulator's renderer and calibration, so
 * that every tool places a lamp or a camera by one formula.
 *
 * World frame (docs/rig-file.md): z up along the turntable axis, origin at the turntable
 * centre, millimetres. The object frame turns with the turntable: a world direction is
 * rotated by minus the turntable angle about z. Angles that are NAN (the rig has no axis of
 * that role) count as 0. All functions are pure. */
#pragma once

#include <stdbool.h>

#include "pose.h"
#include "rigconf.h"

/* World position p (mm) of lamp l with the light arm at light_arm_deg. */
void riggeom_lamp_position(const struct rig_switch_conf *l, double light_arm_deg, double p[3]);

/* World position p (mm) of the projection centre of camera c with the camera arm at
 * camera_arm_deg. */
void riggeom_camera_center(const struct rig_camera_conf *c, double camera_arm_deg, double p[3]);

/* World-to-camera transform of camera c with the camera arm at camera_arm_deg: a world point
 * X is R X + t in the camera's frame (OpenCV convention: x right, y down, z forward, looking
 * at c->target). R is row-major. */
void riggeom_camera_pose(const struct rig_camera_conf *c, double camera_arm_deg, double R[9],
                         double t[3]);

/* Unit vector dir from the turntable centre (the object's origin) to lamp number lamp of rc
 * (a valid index) in the object frame for pose p (light arm and turntable angles; NAN counts as 0).
 */
void riggeom_lamp_dir_object(const struct rig_config *rc, int lamp, const struct gn_pose *p,
                             double dir[3]);

/* Angle in degrees, in [0, 180], between the non-zero vectors a and b. */
double riggeom_angle_deg(const double a[3], const double b[3]);

/* True when the world point x lies in the field of view of camera c (arm at
 * camera_arm_deg), in front of it and inside its image by the pinhole model of fx, fy,
 * cx, cy, width and height (distortion ignored). *off_axis_deg, when not NULL, gets the angle
 * between the optical axis and the direction from the camera to x. */
bool riggeom_in_view(const struct rig_camera_conf *c, double camera_arm_deg, const double x[3],
                     double *off_axis_deg);
