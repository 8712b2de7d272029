/* registry.c - the one explicit table of driver backends, by device class. A new backend
 * adds its ops here (see docs/drivers.md). */
#include <string.h>

#include "common/cleanup.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/camera/sim/api.h"
#include "drivers/registry.h"
#include "drivers/switch/modbus/proto.h"

static const struct axis_ops *const axis_backends[] = {
        &mbax_ops,
};

static const struct sw_ops *const switch_backends[] = {
        &mbsw_ops,
};

static const struct cam_ops *const camera_backends[] = {
        &cam_sim_ops,
};

/* The entry of table whose name is backend, or NULL. Every ops struct starts with a name. */
#define FIND(table, backend)                                                                       \
        ({                                                                                         \
                __typeof__(&*(table)[0]) _found = NULL;                                            \
                for (size_t _i = 0; (backend) && !_found && _i < ELEMENTSOF(table); _i++)          \
                        if (strcmp((table)[_i]->name, (backend)) == 0)                             \
                                _found = (table)[_i];                                              \
                _found;                                                                            \
        })

const struct axis_ops *registry_axis(const char *backend)
{
        return FIND(axis_backends, backend);
}

const struct sw_ops *registry_switch(const char *backend)
{
        return FIND(switch_backends, backend);
}

const struct cam_ops *registry_camera(const char *backend)
{
        return FIND(camera_backends, backend);
}
