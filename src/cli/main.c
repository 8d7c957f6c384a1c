/* sooc3d: git-style command dispatcher. */
#include "cli.h"

#include <stdio.h>
#include <string.h>

static const struct {
    const char *name;
    sooc_cmd_fn fn;
    const char *help;
} g_cmds[] = {
    {"gen", sooc_cmd_gen, "render synthetic RGB-D datasets (unity/blender/tabletop presets, s/m/l/xl scales)"},
    {"train", sooc_cmd_train, "train a SOOC3D model"},
    {"infer", sooc_cmd_infer, "run online inference over a sequence and write the map"},
    {"eval", sooc_cmd_eval, "compute the paper's metrics and tables"},
    {"render", sooc_cmd_render, "draw views, segmentations, uncertainty and map pictures"},
    {"finetune", sooc_cmd_finetune, "per-object NeRF finetuning (EM)"},
    {"mesh", sooc_cmd_mesh, "extract object meshes"},
    {"map", sooc_cmd_map, "list, query or export a stored map"},
    {"model", sooc_cmd_model, "show a checkpoint's configuration, set its inference slots"},
    {"node", sooc_cmd_node, "run the live mapping node from a launch file"},
    {"odometry", sooc_cmd_odometry, "RGB-D odometry over a sequence (TUM trajectory, ATE/RPE)"},
    {"calib", sooc_cmd_calib, "camera intrinsics and hand-eye from board images"},
    {"log", sooc_cmd_log, "describe a ROS bag or MCAP file: channels, camera streams, intrinsics, pose"},
};
#define NCMDS (sizeof g_cmds / sizeof g_cmds[0])

static void usage(FILE *f) {
    fprintf(f, "usage: sooc3d <command> [options]\n\ncommands:\n");
    for (size_t i = 0; i < NCMDS; i++) fprintf(f, "  %-9s %s\n", g_cmds[i].name, g_cmds[i].help);
    fprintf(f, "  %-9s %s\n", "help", "list commands, or `sooc3d help <command>`");
    fprintf(f, "\nRun `sooc3d <command> --help` for a command's options.\n");
}

int main(int argc, char **argv) {
    sooc_log_set_callback(sooc_cli_log, NULL);
    if (argc < 2) { usage(stderr); return 2; }
    const char *name = argv[1];
    if (!strcmp(name, "help") || !strcmp(name, "--help") || !strcmp(name, "-h")) {
        if (argc >= 3) {
            for (size_t i = 0; i < NCMDS; i++)
                if (!strcmp(argv[2], g_cmds[i].name)) {
                    char *hargv[] = {argv[2], "--help", NULL};
                    return g_cmds[i].fn(2, hargv);
                }
            fprintf(stderr, "sooc3d: unknown command '%s'\n", argv[2]);
            return 2;
        }
        usage(stdout);
        return 0;
    }
    if (!strcmp(name, "--version")) { printf("sooc3d 0.1.0\n"); return 0; }
    for (size_t i = 0; i < NCMDS; i++)
        if (!strcmp(name, g_cmds[i].name)) return g_cmds[i].fn(argc - 1, argv + 1);
    fprintf(stderr, "sooc3d: unknown command '%s'\n\n", name);
    usage(stderr);
    return 2;
}
