/* sooc3d node: placeholder until its module lands; it fails loudly rather than pretending. */
#include "cli.h"

#include <stdio.h>

int sooc_cmd_node(int argc, char **argv) {
    (void)argc;
    (void)argv;
    fprintf(stderr, "sooc3d node: not built yet in this version\n");
    return 2;
}
