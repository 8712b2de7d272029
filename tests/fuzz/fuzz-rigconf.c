/* fuzz-rigconf.c - libFuzzer target of the rig file loader (common/rigconf.c over
 * common/yconf.c and libfyaml, with every backend's map parser of drivers/registry.c): the
 * input is a rig file, loaded from a scratch file as goniod loads it. GONIO_FUZZ is set, so
 * that ${GONIO_FUZZ} expands as well as the ${VAR:-default} of the example rigs. */
#include <stdlib.h>

#include "common/rigconf.h"
#include "drivers/registry.h"
#include "fuzz.h"

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
        setenv("GONIO_FUZZ", "/dev/null", 1);
        return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
        const char *path = fuzz_file(data, size, ".yaml");
        struct rig_config *rc = NULL;
        char err[512];

        if (rigconf_load(path, registry_backends, &rc, err, sizeof(err)) == 0 && !rc)
                abort();
        rigconf_free(rc);
        return 0;
}
