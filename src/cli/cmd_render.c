/* sooc3d render: placeholder until its module lands; it fails loudly rather than pretending. */
#include "cli.h"

#include <stdio.h>

int sooc_cmd_render(int argc, char **argv) {
    (void)argc;
    (void)argv;
    fprintf(stderr, "sooc3d render: not built yet in this version\n");
    return 2;
}
