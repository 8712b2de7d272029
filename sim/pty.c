/* pty.c - pseudo-terminals at the rig's port paths (see pty.h). */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include "common/log.h"
#include "sim/pty.h"

static int open_raw(struct sim_pty *p, const char *who)
{
        struct termios t;

        p->master = posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
        if (p->master < 0 || grantpt(p->master) < 0 || unlockpt(p->master) < 0)
                return log_error_errno(errno, "%s: cannot open a pty: %m", who);
        int r = ptsname_r(p->master, p->path, sizeof p->path);
        if (r != 0)
                return log_error_errno(r, "%s: ptsname: %m", who);
        p->slave = open(p->path, O_RDWR | O_NOCTTY | O_CLOEXEC);
        if (p->slave < 0 || tcgetattr(p->slave, &t) < 0)
                return log_error_errno(errno, "%s: cannot open %s: %m", who, p->path);
        cfmakeraw(&t);
        if (tcsetattr(p->slave, TCSANOW, &t) < 0 ||
            fcntl(p->master, F_SETFL, fcntl(p->master, F_GETFL) | O_NONBLOCK) < 0)
                return log_error_errno(errno, "%s: cannot set up %s: %m", who, p->path);
        return 0;
}

/* Points link at the pty's slave, replacing a stale symlink. */
static int make_link(struct sim_pty *p, const char *link, const char *who)
{
        struct stat st;

        if (snprintf(p->link, sizeof p->link, "%s", link) >= (int)sizeof p->link) {
                p->link[0] = '\0';
                return log_error_errno(SYNTHETIC_ERRNO(ENAMETOOLONG), "%s: %s: path too long", who,
                                       link);
        }
        if (lstat(link, &st) == 0) {
                if (!S_ISLNK(st.st_mode)) {
                        p->link[0] = '\0';
                        return log_error_errno(SYNTHETIC_ERRNO(EEXIST),
                                               "%s: %s exists and is not a symlink", who, link);
                }
                (void)unlink(link);
        }
        if (symlink(p->path, link) < 0) {
                p->link[0] = '\0';
                return log_error_errno(errno, "%s: cannot link %s to %s: %m", who, link, p->path);
        }
        return 0;
}

int sim_pty_open(struct sim_pty *p, const char *link, const char *who)
{
        *p = SIM_PTY_NULL;
        int r = open_raw(p, who);
        if (r >= 0 && link)
                r = make_link(p, link, who);
        return r;
}

void sim_pty_close(struct sim_pty *p)
{
        char target[RIG_PATH_MAX];

        if (p->link[0]) {
                ssize_t n = readlink(p->link, target, sizeof target - 1);
                if (n >= 0) {
                        target[n] = '\0';
                        if (strcmp(target, p->path) == 0)
                                (void)unlink(p->link);
                }
        }
        if (p->slave >= 0)
                close(p->slave);
        if (p->master >= 0)
                close(p->master);
        *p = SIM_PTY_NULL;
}
