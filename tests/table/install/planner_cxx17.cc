// An out-of-tree C++17 planner (test_table_install): the same checks as
// planner_c11.c through <sooc3d/table.h> in C++, with records copied into a
// std::vector (the header keeps them trivially copyable in C++).
#include <sooc3d/table.h>

#include <cstdio>
#include <string>
#include <type_traits>
#include <vector>

static_assert(std::is_trivially_copyable<sooc_table_record>::value, "records copy in C++");
static_assert(sizeof(sooc_table_record) == SOOC_TABLE_RECORD_SIZE, "record size");

int main(int argc, char **argv) {
    if (argc != 2) return 2;
    sooc_table_reader *r = nullptr;
    int rc = sooc_table_open_reader(argv[1], &r);
    if (rc != 0) {
        std::fprintf(stderr, "C++17 planner: open '%s': %s\n", argv[1], sooc_table_strerror(rc));
        return 1;
    }
    std::vector<sooc_table_record> recs(sooc_table_capacity(r));
    uint32_t n = 0;
    uint64_t epoch = 0;
    sooc_table_info info{};
    rc = sooc_table_snapshot(r, recs.data(), static_cast<uint32_t>(recs.size()), &n, &epoch);
    if (rc == 0) rc = sooc_table_get_info(r, &info);
    bool bad = rc != 0;
    if (bad) {
        std::fprintf(stderr, "C++17 planner: %s\n", sooc_table_strerror(rc));
    } else {
        recs.resize(n);
        std::vector<sooc_table_record> copy = recs;  // needs copyable records
        bad = n != 3 || std::string(info.frame_id) != "map" || info.latent_model_id != 0x5eedull;
        for (uint32_t i = 0; i < n && !bad; i++) {
            const sooc_table_record &c = copy[i];
            float xr, yr, zr, yawr;
            sooc_table_pose_rep103(&c, &xr, &yr, &zr, &yawr, nullptr);
            bad = c.object_id != 11 + i || c.x != 0.5f * static_cast<float>(c.object_id) ||
                  xr != 1.0f || yr != -c.x;
        }
        sooc_table_liveness live{};
        if (sooc_table_writer_alive(r, &live) != 1) bad = true;
        std::printf("C++17 planner: epoch %llu, %u objects (first id %llu), frame %s, %s\n",
                    static_cast<unsigned long long>(epoch), n,
                    n ? static_cast<unsigned long long>(copy[0].object_id) : 0ull,
                    info.frame_id, bad ? "MISMATCH" : "ok");
    }
    sooc_table_close_reader(r);
    return bad ? 1 : 0;
}
