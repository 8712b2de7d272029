/* opt.c - names and lookup of driver option tables (see opt.h). */
#include <stddef.h>

#include "drivers/opt.h"

const char *opt_key_name(enum opt_key key)
{
        static const char *const names[] = {
                [OPT_POSITION] = "position", [OPT_VELOCITY] = "velocity", [OPT_ACCEL] = "accel",
                [OPT_HOME] = "home",         [OPT_STOP] = "stop",         [OPT_STATE] = "state",
                [OPT_EXPOSURE] = "exposure", [OPT_GAIN] = "gain",         [OPT_BITS] = "bits",
        };

        if ((unsigned)key >= sizeof(names) / sizeof(names[0]) || !names[key])
                return "unknown";
        return names[key];
}

const struct opt_desc *opt_find(const struct opt_desc *opts, int n, enum opt_key key)
{
        for (int i = 0; i < n; i++)
                if (opts[i].key == key)
                        return &opts[i];
        return NULL;
}
