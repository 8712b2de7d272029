/* clock.c - wall and monotonic clocks in nanoseconds (see clock.h). */
#include <time.h>

#include "clock.h"

static uint64_t clock_ns(clockid_t id)
{
        struct timespec ts;

        (void)clock_gettime(id, &ts);
        return (uint64_t)ts.tv_sec * UINT64_C(1000000000) + (uint64_t)ts.tv_nsec;
}

uint64_t gn_realtime_ns(void)
{
        return clock_ns(CLOCK_REALTIME);
}

uint64_t gn_monotonic_ns(void)
{
        return clock_ns(CLOCK_MONOTONIC);
}
