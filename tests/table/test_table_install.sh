#!/bin/sh
# The table component as a planner's developer meets it, from outside the tree:
#  1. a FRESH build directory: the one documented command
#     `cmake --build <b> --target install_table` builds and installs the
#     component (DESTDIR staging into <tmp>/root/usr/local, a clean prefix);
#     the installed libraries carry no RPATH/RUNPATH;
#  2. a live table written by table_test_writer;
#  3. a C11 and a C++17 planner built through pkg-config and through
#     find_package(sooc3d_table) (shared and static) read it and check its
#     objects; shared builds run with LD_LIBRARY_PATH = the prefix's libdir,
#     which is what `ldconfig` provides for a real install (docs/shm.md §8);
#  4. the installed C and Python examples read it too;
#  5. `cmake --install` of this build (everything) if all of it is built
#     (the default target; scripts/test.sh builds it).
# Usage: test_table_install.sh <build dir> <source dir> <writer> <cc> <c++>
set -eu
build=$1; src=$2; writer=$3; cc=$4; cxx=$5
here=$src/tests/table/install
command -v pkg-config >/dev/null || { echo "pkg-config missing: skipped"; exit 77; }
command -v "$cxx" >/dev/null || { echo "no C++ compiler ($cxx): skipped"; exit 77; }
tmp=$build/table_install_test
rm -rf "$tmp"; mkdir -p "$tmp"
wpid=
cleanup() {
  exec 3>&- 2>/dev/null || true
  [ -n "$wpid" ] && { kill "$wpid" 2>/dev/null || true; wait "$wpid" 2>/dev/null || true; }
  rm -rf "$tmp"
}
trap cleanup EXIT
fail() { echo "test_table_install: FAIL: $*"; exit 1; }

# ---- 1. fresh build directory, one command
launcher=
command -v ccache >/dev/null && launcher=-DCMAKE_C_COMPILER_LAUNCHER=ccache
cmake -S "$src" -B "$tmp/fresh" -DCMAKE_BUILD_TYPE=Release -DSOOC_BUILD_TESTS=OFF \
      -DSOOC_BUILD_BENCH=OFF -DCMAKE_INSTALL_PREFIX=/usr/local $launcher >"$tmp/configure.log" 2>&1 \
  || { cat "$tmp/configure.log"; fail "configure of a fresh build directory"; }
DESTDIR=$tmp/root cmake --build "$tmp/fresh" --target install_table -j2 >"$tmp/install.log" 2>&1 \
  || { cat "$tmp/install.log"; fail "cmake --build <fresh> --target install_table"; }
prefix=$tmp/root/usr/local
pc=$(find "$prefix" -name sooc3d_table.pc)
[ -n "$pc" ] || fail "sooc3d_table.pc not installed"
libdir=$(dirname "$(dirname "$pc")")
for f in include/sooc3d/table.h bin/sooc3d-planner-example share/sooc3d/sooc3d-planner-example.py; do
  [ -e "$prefix/$f" ] || fail "$f not installed"
done
for f in libsooc3d_table.so libsooc3d_table.so.1 libsooc3d_table.a cmake/sooc3d_table/sooc3d_tableConfig.cmake; do
  [ -e "$libdir/$f" ] || fail "$libdir/$f not installed"
done
echo "installed into $prefix: $(cd "$prefix" && find . -type f -o -type l | sort | tr '\n' ' ')"
if command -v readelf >/dev/null; then
  for f in "$libdir/libsooc3d_table.so.1" "$prefix/bin/sooc3d-planner-example"; do
    if readelf -d "$f" | grep -q 'R.*PATH'; then fail "$f carries an RPATH/RUNPATH"; fi
  done
  echo "no RPATH/RUNPATH in the installed library and example"
fi

# ---- 2. a live table
name=test_install_$$
mkfifo "$tmp/ctl"
"$writer" "$name" 60 <"$tmp/ctl" >"$tmp/writer.out" &
wpid=$!
exec 3>"$tmp/ctl"
i=0
until grep -q ready "$tmp/writer.out" 2>/dev/null; do
  i=$((i + 1)); [ $i -le 100 ] || fail "table_test_writer did not start"
  sleep 0.1
done

# ---- 3. consumers: pkg-config
export PKG_CONFIG_PATH="$libdir/pkgconfig"
flags=$(pkg-config --cflags --libs sooc3d_table)
echo "pkg-config --cflags --libs sooc3d_table: $flags"
"$cc" -std=c11 -Wall -Wextra -Werror -pedantic "$here/planner_c11.c" -o "$tmp/c11_pc" $flags
"$cxx" -std=c++17 -Wall -Wextra -Werror -pedantic "$here/planner_cxx17.cc" -o "$tmp/cxx17_pc" $flags
# What a planner meets before `ldconfig` (docs/shm.md §8): the loader cannot find the library.
set +e
env -u LD_LIBRARY_PATH "$tmp/c11_pc" "$name" >/dev/null 2>"$tmp/noldconfig.err"
rc=$?
set -e
echo "without ldconfig or LD_LIBRARY_PATH: exit $rc $(head -c 120 "$tmp/noldconfig.err")"
LD_LIBRARY_PATH=$libdir "$tmp/c11_pc" "$name" || fail "C11 planner (pkg-config)"
LD_LIBRARY_PATH=$libdir "$tmp/cxx17_pc" "$name" || fail "C++17 planner (pkg-config)"
# ---- consumers: find_package
CC=$cc CXX=$cxx cmake -S "$here" -B "$tmp/proj" -DCMAKE_PREFIX_PATH="$prefix" \
   -DCMAKE_BUILD_TYPE=Release >"$tmp/proj.log" 2>&1 || { cat "$tmp/proj.log"; fail "find_package project"; }
cmake --build "$tmp/proj" >>"$tmp/proj.log" 2>&1 || { cat "$tmp/proj.log"; fail "find_package build"; }
for p in planner_c11 planner_cxx17 planner_c11_static; do
  LD_LIBRARY_PATH=$libdir "$tmp/proj/$p" "$name" || fail "$p (find_package)"
done
# ---- 4. the installed examples
"$prefix/bin/sooc3d-planner-example" "$name" --once >"$tmp/ex.out" || fail "installed C example"
grep -q "objects 3" "$tmp/ex.out" || { cat "$tmp/ex.out"; fail "installed C example output"; }
if [ -x /usr/bin/python3 ]; then
  /usr/bin/python3 "$prefix/share/sooc3d/sooc3d-planner-example.py" "$name" --once >"$tmp/py.out" \
    || fail "installed Python example"
  grep -q "objects 3" "$tmp/py.out" || { cat "$tmp/py.out"; fail "installed Python example output"; }
fi
if [ -x /usr/bin/python3 ]; then   # the module itself, from where it was installed
  pyd=$(ls -d "$prefix"/lib/python3.*/dist-packages 2>/dev/null | head -1)
  [ -e "$pyd/sooc3d_table.py" ] || fail "sooc3d_table.py not installed under $prefix/lib/python3.N/dist-packages"
  n=$(cd / && PYTHONPATH=$pyd /usr/bin/python3 -c "import sooc3d_table; print(sooc3d_table.Table('$name').snapshot()[2])") \
    || fail "import sooc3d_table from the installed module"
  [ "$n" = 3 ] || fail "sooc3d_table.Table snapshot: $n objects, want 3"
fi
echo "installed C and Python examples, and the Python module, read the table"
exec 3>&-
wait "$wpid" || fail "table_test_writer exit status"
wpid=
[ ! -e "/dev/shm/sooc3d.v1.$name" ] || fail "writer did not unlink its table"

# ---- 5. everything
if [ -x "$build/bin/sooc3d" ] && [ -e "$build/lib/libsooc3d_table.so" ] && [ -x "$build/bin/sooc3d-planner-example" ]; then
  cmake --install "$build" --prefix "$tmp/all" >"$tmp/all.log" 2>&1 || { cat "$tmp/all.log"; fail "cmake --install (everything)"; }
  for f in bin/sooc3d share/sooc3d/calib/kinect_v1.yaml share/sooc3d/launch/replay_demo.yaml \
           share/sooc3d/models/sooc3d_unity/model.bin include/sooc3d/table.h; do
    [ -e "$tmp/all/$f" ] || fail "everything install: $f missing"
  done
  echo "everything installed: $(cd "$tmp/all" && find . -type f | wc -l) files"
else
  echo "sooc3d, libsooc3d_table.so or the example not built in $build (partial build): the install of everything was not tried"
fi
echo "test_table_install: ok"
