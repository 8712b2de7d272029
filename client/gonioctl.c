/* gonioctl.c - the command-line client of goniod: parse the command line, run one
 * command, exit with its code (docs/gonioctl.md, gonioctl(1)). */
#include <stdio.h>

#include "client/args.h"
#include "client/cmd.h"
#include "protocol/proto.h"

int main(int argc, char **argv)
{
        struct args a;
        int r;

        r = args_parse(argc, argv, &a);
        if (r < 0)
                r = EXIT_USAGE;
        else if (a.help)
                cmd_usage(stdout);
        else if (a.version)
                printf("gonioctl %s (protocol %d)\n", GONIOCTL_VERSION, PROTO_VERSION);
        else
                r = cmd_run(&a);
        args_done(&a);
        return r;
}
