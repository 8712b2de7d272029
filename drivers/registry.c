/* registry.c - the one explicit table of driver backends: each entry names a backend as the
 * rig file does, its device class, the parser of its backend map and its ops. A new backend
 * adds its entry here (see docs/drivers.md). */
#include <string.h>

#include "drivers/axis/gpio/proto.h"
#include "drivers/axis/gcode/proto.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/camera/libcamera/api.h"
#include "drivers/camera/sim/api.h"
#ifdef GONIO_HAVE_V4L2
#include "drivers/camera/v4l2/api.h"
#endif
#include "drivers/registry.h"
#include "drivers/switch/gpio/proto.h"
#include "drivers/switch/gcode/proto.h"
#include "drivers/switch/modbus/proto.h"
#ifdef GONIO_USBRELAY
#include "drivers/switch/usbrelay/proto.h"
#endif

/* One backend a line; some only with their library. */
/* clang-format off */
const struct rig_backend *const registry_backends[] = {
        &mbax_backend,
        &mbsw_backend,
        &gcax_backend,
        &gcsw_backend,
        &cam_sim_backend,
        &cam_lc_backend,
#ifdef GONIO_USBRELAY
        &usbrelay_backend,
#endif
#ifdef GONIO_HAVE_GPIOD /* libgpiod found (-Dgpio) */
        &gpst_backend,
        &gpsw_backend,
#endif
#ifdef GONIO_HAVE_V4L2 /* linux/videodev2.h found (-Dv4l2) */
        &cam_v4l2_backend,
#endif
        NULL,
};
/* clang-format on */

/* The ops of the backend of class cls named name, or NULL. */
static const void *find(enum rig_class cls, const char *name)
{
        for (const struct rig_backend *const *b = registry_backends; name && *b; b++)
                if ((*b)->cls == cls && strcmp((*b)->name, name) == 0)
                        return (*b)->ops;
        return NULL;
}

const struct axis_ops *registry_axis(const char *backend)
{
        return find(RIG_CLASS_AXIS, backend);
}

const struct sw_ops *registry_switch(const char *backend)
{
        return find(RIG_CLASS_SWITCH, backend);
}

const struct cam_ops *registry_camera(const char *backend)
{
        return find(RIG_CLASS_CAMERA, backend);
}
