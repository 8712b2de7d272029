/* registry.h - the one explicit table of driver backends, by device class. */
#pragma once

#include "common/rigconf.h"
#include "drivers/axis/axis.h"
#include "drivers/camera/camera.h"
#include "drivers/switch/switch.h"

/* Every backend, NULL-terminated: the table to give rigconf_load(), so that each device's
 * backend map is parsed by its backend when the rig file loads. */
extern const struct rig_backend *const registry_backends[];

/* Backend ops by rig-file name; NULL when unknown. */
const struct axis_ops *registry_axis(const char *backend);
const struct sw_ops *registry_switch(const char *backend);
const struct cam_ops *registry_camera(const char *backend);
