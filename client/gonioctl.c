/* gonioctl.c - the command-line client of goniod: parse the command line, run one
 * command, exit with its code (docs/gonioctl.md, gonioctl(1)). */
#include <stdio.h>

#include "client/args.h"
#include "client/cmd.h"
#include "gonio_version.h"
#include "protocol/proto.h"

int main(int argc, char **argv)
{
        struct args a;
        int r;

        r = args_parse(argc, argv, &a);
        if (r < 0)
                r = cmd_usage_failed(&a);
        else if (a.help)
                r = cmd_help(&a);
        else if (a.version)
                printf("gonioctl %s (protocol %d)\n", GONIO_VERSION, PROTO_VERSION);
        else
                r = cmd_run(&a);
        args_done(&a);
        return r;
}
