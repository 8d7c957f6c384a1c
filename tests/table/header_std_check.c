/* test_table_header_std: include/sooc3d/table.h compiled as C and C++ in each
 * standard a planner may use (test_table_header_std.sh builds this file with
 * -std=c11/c17 as C and -std=c++17/c++20/c++23 as C++, -Wall -Wextra -Werror
 * -pedantic, and runs it). It copies records by value (C++ needs them
 * trivially copyable), checks the layout at run time as well and converts a
 * pose with the inline sooc_table_pose_rep103(). No library is linked. */
#include <sooc3d/table.h>

#include <stddef.h>
#include <stdio.h>
#include <string.h>

#ifdef __cplusplus
#include <type_traits>
static_assert(std::is_trivially_copyable<sooc_table_record>::value, "record copyable");
static_assert(std::is_standard_layout<sooc_table_header>::value, "header standard layout");
#define LANG "C++"
#define STD_VERSION __cplusplus
#else
#define LANG "C"
#define STD_VERSION __STDC_VERSION__
#endif

int main(void) {
    sooc_table_record a, b;
    memset((void *)&a, 0, sizeof a);
    a.object_id = 7;
    a.x = 1.0f;
    a.z = 2.0f;
    a.y = 0.5f;
    a.yaw = 0.25f;
    a.cov_xzyaw[0] = 1.0f;
    a.cov_xzyaw[3] = 4.0f;
    a.cov_xzyaw[4] = 0.5f;
    b = a; /* by value */
    float x, y, z, yaw, cov[6];
    sooc_table_pose_rep103(&b, &x, &y, &z, &yaw, cov);
    int ok = sizeof(sooc_table_record) == SOOC_TABLE_RECORD_SIZE &&
             sizeof(sooc_table_header) == SOOC_TABLE_HEADER_SIZE &&
             offsetof(sooc_table_record, latent) == 128 &&
             offsetof(sooc_table_header, table_seq) == 104 &&
             offsetof(sooc_table_header, T_src_map) == 280 && b.object_id == 7 && x == -2.0f &&
             y == -1.0f && z == 0.5f && yaw == 0.25f && cov[0] == 4.0f && cov[3] == 1.0f &&
             cov[2] == -0.5f;
    printf("%s %ld: table.h %s\n", LANG, (long)STD_VERSION, ok ? "ok" : "MISMATCH");
    return ok ? 0 : 1;
}
