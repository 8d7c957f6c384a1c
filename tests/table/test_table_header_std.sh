#!/bin/sh
# include/sooc3d/table.h as C11, C17, C++17, C++20 and C++23: each
# build of header_std_check.c must compile with -Wall -Wextra -Werror -pedantic
# and run. Usage: test_table_header_std.sh <source dir> <work dir> <cc> <c++>
set -eu
src=$1; out=$2; cc=$3; cxx=$4
command -v "$cxx" >/dev/null || { echo "no C++ compiler ($cxx): skipped"; exit 77; }
mkdir -p "$out"
flags="-Wall -Wextra -Werror -pedantic -I$src/include"
status=0
for std in c11 c17; do
  if "$cc" -std=$std $flags -x c "$src/tests/table/header_std_check.c" -o "$out/check_$std" \
     && "$out/check_$std"; then :; else echo "FAIL: table.h as $std"; status=1; fi
done
for std in c++17 c++20 c++23; do
  if "$cxx" -std=$std $flags -x c++ "$src/tests/table/header_std_check.c" -o "$out/check_$std" \
     && "$out/check_$std"; then :; else echo "FAIL: table.h as $std"; status=1; fi
done
[ $status -eq 0 ] && echo "test_table_header_std: ok"
exit $status
