/* registry.h - the one explicit table of driver backends, by device class. */
#pragma once

#include "drivers/axis/axis.h"
#include "drivers/camera/camera.h"
#include "drivers/switch/switch.h"

/* Backend ops by rig-file name; NULL when unknown. */
const struct axis_ops *registry_axis(const char *backend);
const struct sw_ops *registry_switch(const char *backend);
const struct cam_ops *registry_camera(const char *backend);
