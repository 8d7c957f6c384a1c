/* `sooc3d node` linked with the fake mapper: tests/node runs it as a child
 * process (signals, exit codes) without the trained model. */
#include <stdio.h>
#include <string.h>

#include "cli.h"

int sooc_cli_fail(const char *cmd, sooc_status s) {
    fprintf(stderr, "sooc3d %s: error (%s): %s\n", cmd, sooc_status_str(s), sooc_errmsg());
    return 1;
}

int sooc_cli_wants_help(int argc, char **argv) {
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) return 1;
    return 0;
}

static void cli_log(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    static const char *tag[] = {"debug", "info", "warn", "error", "fatal"};
    fprintf(stderr, "[%s] %s\n", tag[level], msg);
}

int main(int argc, char **argv) {
    sooc_log_set_callback(cli_log, NULL);
    return sooc_cmd_node(argc, argv);
}
