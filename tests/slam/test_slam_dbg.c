#include <stdio.h>
#include <string.h>
#include <math.h>
#include <stdlib.h>
#include "sooc3d/slam.h"
#include "sooc3d/seq.h"
#include "sooc3d/geom.h"
int main(int argc, char **argv) {
    sooc_seq *seq; sooc_seq_open_params sp; sooc_seq_open_params_default(&sp);
    if (sooc_seq_open(&seq, "/work/shared/real/7scenes_redkitchen", &sp)) { printf("%s\n", sooc_errmsg()); return 1; }
    sooc_slam_params p; sooc_slam_params_default(&p); p.loop_closure = 0;
    sooc_odom_params_7scenes_color(&p.odom, 640, 480);
    sooc_slam *s; if (sooc_slam_create(&s, &p, NULL)) { printf("%s\n", sooc_errmsg()); return 1; }
    int N = argc > 1 ? atoi(argv[1]) : 60;
    sooc_frame f; memset(&f, 0, sizeof f);
    for (int i = 0; i < N; i++) { sooc_seq_read(seq, i, &f); sooc_slam_result r; if (sooc_slam_track(s, &f, &r)) { printf("%s\n", sooc_errmsg()); return 1;} }
    int64_t nk = sooc_slam_keyframe_count(s);
    for (int64_t k = 1; k < nk; k++) for (int64_t d = 1; d <= 2 && k-d>=0; d++) {
        double Ta[16], Tb[16], inv[16], R[16], T[16]; int ok, inl;
        sooc_slam_keyframe(s, k, NULL, NULL, NULL, Ta); sooc_slam_keyframe(s, k-d, NULL, NULL, NULL, Tb);
        sooc_se3_inverse(inv, Tb); sooc_se3_mul(R, inv, Ta);
        if (sooc_slam_verify_pair(s, k, k-d, &ok, T, &inl)) { printf("%s\n", sooc_errmsg()); return 1; }
        printf("kf %lld vs %lld: ok %d inl %d  odo t %.3f %.3f %.3f  ver t %.3f %.3f %.3f\n", (long long)k, (long long)(k-d), ok, inl, R[3], R[7], R[11], T[3], T[7], T[11]);
    }
    return 0;
}
