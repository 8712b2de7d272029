/* threads_preload.c - an LD_PRELOAD module whose constructor starts a thread before main(),
 * as OpenBLAS does in every program that links OpenCV: gonioctl-peer-threads runs the peer
 * tests with it, so that Ctrl-C and SIGTERM must be handled whatever threads exist. */
#include <pthread.h>
#include <unistd.h>

static void *idle_forever(void *arg)
{
        for (;;)
                pause();
        return arg;
}

__attribute__((constructor)) static void start_thread(void)
{
        pthread_t t;

        if (pthread_create(&t, NULL, idle_forever, NULL) == 0)
                pthread_detach(t);
}
