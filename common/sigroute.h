/* sigroute.h - takes termination signals in one thread (sd-event's signalfd in goniod,
 * sigwait in gonio-sim) even when a library started threads before main() (OpenBLAS does,
 * under OpenCV) that do not block them: such a thread would otherwise receive the signal
 * and die of its default action, skipping the program's orderly shutdown. */
#pragma once

#include <stddef.h>

/* Blocks sigs in the calling thread and installs a handler that, in any other thread the
 * kernel picks, passes the signal on to the calling thread, where it stays pending for its
 * signalfd or sigwait. Call it once, from the thread that takes the signals, before it
 * starts threads of its own. Returns 0 or -errno. */
int gn_sigroute_here(const int *sigs, size_t n);
