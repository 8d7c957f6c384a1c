/* sooc3d gen: placeholder until its module lands; it fails loudly rather than pretending. */
#include "cli.h"

#include <stdio.h>

int sooc_cmd_gen(int argc, char **argv) {
    (void)argc;
    (void)argv;
    fprintf(stderr, "sooc3d gen: not built yet in this version\n");
    return 2;
}
