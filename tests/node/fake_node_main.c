/* `sooc3d node` linked with the fake mapper: tests/node runs it as a child
 * process (signals, exit codes) without the trained model. The CLI helpers
 * come from src/cli/cli_util.c. */
#include "cli.h"

int main(int argc, char **argv) {
    sooc_log_set_callback(sooc_cli_log, NULL);
    return sooc_cmd_node(argc, argv);
}
