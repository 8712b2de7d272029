/* fuzz-sessconf.c - libFuzzer target of the session file loader (common/sessconf.c over
 * common/yconf.c): the input is a session file, parsed against each example rig
 * (examples/rigs, loaded once) as `gonioctl session plan` does. */
#include <stdio.h>
#include <stdlib.h>

#include "common/sessconf.h"
#include "drivers/registry.h"
#include "fuzz.h"

static const char *const rig_files[] = {"sim.yaml", "paper.yaml", "ciclop.yaml", "lab.yaml"};
#define N_RIGS (sizeof(rig_files) / sizeof(rig_files[0]))

static struct rig_config *rigs[N_RIGS];

static void free_rigs(void)
{
        for (size_t i = 0; i < N_RIGS; i++)
                rigs[i] = rigconf_free(rigs[i]);
}

/* Loads the example rigs; one whose backends this build lacks (lab.yaml without libgpiod) is
 * left out. */
int LLVMFuzzerInitialize(int *argc, char ***argv)
{
        for (size_t i = 0; i < N_RIGS; i++) {
                char path[512], err[512];

                snprintf(path, sizeof(path), "%s/examples/rigs/%s", GONIO_SOURCE_ROOT,
                         rig_files[i]);
                if (rigconf_load(path, registry_backends, &rigs[i], err, sizeof(err)) < 0)
                        fprintf(stderr, "fuzz-sessconf: %s left out: %s\n", rig_files[i], err);
        }
        atexit(free_rigs);
        return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
        char *text = fuzz_cstr(data, size);

        for (size_t i = 0; i < N_RIGS; i++) {
                struct session_conf *sc = NULL;
                char err[512];

                if (rigs[i])
                        sessconf_load_string("fuzz.yaml", text, rigs[i], &sc, err, sizeof(err));
                sessconf_free(sc);
        }
        free(text);
        return 0;
}
