/* sim.c - the "sim" transport: a Unix stream socket to gonio-sim's frame server (its
 * path is the bus's port), read and written through the stream helpers of
 * transport.c. */
#include <errno.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "drivers/transport/transport.h"

static int sim_open(struct transport *t)
{
        const char *path = t->conf->port;
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        _cleanup_close_ int fd = -EBADF;

        if (strlen(path) >= sizeof(sa.sun_path))
                return transport_set_cause(t, -ENAMETOOLONG, "socket path %s: %m", path);
        strcpy(sa.sun_path, path);
        fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
        if (fd < 0)
                return transport_set_cause(t, -errno, "cannot create a socket: %m");
        if (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0)
                return transport_set_cause(t, -errno, "cannot connect to gonio-sim at %s: %m",
                                           path);
        t->fd = TAKE_FD(fd);
        return 0;
}

static void sim_close(struct transport *t)
{
        close(t->fd);
}

const struct transport_ops transport_sim_ops = {
        .name = "sim",
        .type = RIG_BUS_SIM,
        .stream = true,
        .socket = true,
        .open = sim_open,
        .close = sim_close,
};
