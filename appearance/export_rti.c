/* export_rti.c - the RTI exports (export.h): a placeholder until the RTI writer lands (it
 * replaces this file wholesale). */
#include <errno.h>
#include <stdio.h>

#include "appearance/export.h"

int ap_export_rti(struct ds *d, const char *ds_dir, const char *dir, const struct ap_export_opts *o,
                  char *err, size_t errlen)
{
        (void)d, (void)ds_dir, (void)dir, (void)o;
        snprintf(err, errlen, "rti: not built yet");
        return -EOPNOTSUPP;
}
