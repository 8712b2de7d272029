/* registry.c - the one explicit table of driver backends: each entry names a backend as the
 * rig file does, its device class, the parser of its backend map and its ops. A new backend
 * adds its entry here (see docs/drivers.md). */
#include <string.h>

#include "drivers/axis/modbus/proto.h"
#include "drivers/camera/sim/api.h"
#ifdef GN_HAVE_V4L2
#include "drivers/camera/v4l2/api.h"
#endif
#include "drivers/registry.h"
#include "drivers/switch/modbus/proto.h"

const struct rig_backend *const registry_backends[] = {
        &mbax_backend,
        &mbsw_backend,
        &cam_sim_backend,
#ifdef GN_HAVE_V4L2
        &cam_v4l2_backend,
#endif
        NULL,
};

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
