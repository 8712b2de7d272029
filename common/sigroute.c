/* sigroute.c - termination signals routed to one thread (sigroute.h). */
#include <errno.h>
#include <pthread.h>
#include <signal.h>

#include "common/sigroute.h"

/* The thread that takes the routed signals: the one state a signal handler needs. */
static pthread_t route_target;

static void route_signal(int sig)
{
        int saved = errno;

        pthread_kill(route_target, sig); /* blocked there: pending until taken */
        errno = saved;
}

int gn_sigroute_here(const int *sigs, size_t n)
{
        struct sigaction sa = {.sa_handler = route_signal, .sa_flags = SA_RESTART};
        sigset_t set;
        int r;

        sigemptyset(&set);
        sigemptyset(&sa.sa_mask);
        for (size_t i = 0; i < n; i++)
                sigaddset(&set, sigs[i]);
        route_target = pthread_self();
        r = pthread_sigmask(SIG_BLOCK, &set, NULL);
        if (r > 0)
                return -r;
        for (size_t i = 0; i < n; i++)
                if (sigaction(sigs[i], &sa, NULL) < 0)
                        return -errno;
        return 0;
}
