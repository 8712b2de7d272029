/* local.c - the "local" transport: no line at all. A bus of type local is only a worker
 * thread for devices whose backend opens them itself (a V4L2 node, a gpiochip, a USB
 * device, a libcamera camera), so their blocking calls stay off the event loop. */
#include "drivers/transport/transport.h"

static int local_open(struct transport *t)
{
        return 0;
}

static void local_close(struct transport *t)
{
}

const struct transport_ops transport_local_ops = {
        .name = "local",
        .type = RIG_BUS_LOCAL,
        .open = local_open,
        .close = local_close,
};
