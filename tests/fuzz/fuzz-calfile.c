/* fuzz-calfile.c - libFuzzer target of the calibration file reader (calib/calfile.c,
 * cal_file_read: what the scan reconstruction and the appearance model read): the input is
 * a calibration.yaml, read from a scratch file. */
#include <stdlib.h>

#include "calib/calfile.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
        const char *path = fuzz_file(data, size, ".yaml");
        struct cal_file *f = malloc(sizeof(*f));
        char err[512];

        if (!f)
                return 0;
        if (cal_file_read(path, f, err, sizeof(err)) == 0 &&
            (f->n_cameras > CAL_FILE_MAX || f->n_turntables > CAL_FILE_MAX ||
             f->n_lasers > CAL_FILE_MAX || f->n_lamps > CAL_FILE_MAX))
                abort();
        free(f);
        return 0;
}
