#!/bin/sh
# Install the `table` component into a temporary prefix, then build a tiny
# planner against it twice: with pkg-config and with find_package(sooc3d_table).
# Usage: test_table_install.sh <build dir> <this dir> <C compiler> [asan=ON|OFF]
set -eu
build=$1; here=$2; cc=$3; asan=${4:-asan=OFF}
case "$asan" in asan=ON|asan=on|asan=1|asan=TRUE)
  echo "SOOC_ASAN build: the installed library needs the ASan runtime; skipped"; exit 77;;
esac
if [ ! -e "$build/lib/libsooc3d_table.so" ]; then
  echo "libsooc3d_table.so not built (build the default target first)"; exit 77
fi
command -v pkg-config >/dev/null || { echo "pkg-config missing"; exit 77; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --component table --prefix "$tmp/prefix" >/dev/null
pc=$(find "$tmp/prefix" -name sooc3d_table.pc)
[ -n "$pc" ] || { echo "sooc3d_table.pc not installed"; exit 1; }
cat > "$tmp/planner.c" <<'C'
#include <sooc3d/table.h>
#include <stdio.h>
int main(void) {
    sooc_table_reader *r = NULL;
    int rc = sooc_table_open_reader("test_install_no_such_table", &r);
    printf("open: %s; schema %016llx\n", sooc_table_strerror(rc),
           (unsigned long long)sooc_table_schema_hash());
    return rc == SOOC_TABLE_ENOENT && sooc_table_schema_hash() == SOOC_TABLE_SCHEMA_HASH ? 0 : 1;
}
C
# 1. pkg-config, shared library
export PKG_CONFIG_PATH="$(dirname "$pc")"
flags=$(pkg-config --cflags --libs sooc3d_table)
echo "pkg-config: $flags"
"$cc" -std=c11 -Wall -Wextra -Werror -pedantic "$tmp/planner.c" -o "$tmp/planner_pc" $flags
LD_LIBRARY_PATH="$(pkg-config --variable=libdir sooc3d_table)" "$tmp/planner_pc"
# 2. CMake package
mkdir -p "$tmp/proj"
cp "$tmp/planner.c" "$tmp/proj/"
cat > "$tmp/proj/CMakeLists.txt" <<'CM'
cmake_minimum_required(VERSION 3.16)
project(planner C)
find_package(sooc3d_table 1 REQUIRED)
add_executable(planner planner.c)
target_link_libraries(planner PRIVATE sooc3d_table::sooc3d_table)
add_executable(planner_static planner.c)
target_link_libraries(planner_static PRIVATE sooc3d_table::sooc3d_table_static)
CM
cmake -S "$tmp/proj" -B "$tmp/proj/b" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/proj/b" >/dev/null
"$tmp/proj/b/planner"
"$tmp/proj/b/planner_static"
echo "test_table_install: ok"
