#!/usr/bin/env bash
# Build grblHAL's Simulator with the abbe plugin from the pinned snapshots.
#
#   port/grblhal/build_sim.sh [--build-dir DIR] [--vendor DIR] [--table MODEL.bin]
#                             [--fixed-point] [--stock]
#
#   --build-dir DIR  where everything goes (default build-grblhal/)
#   --vendor DIR     the snapshots (default $ABBE_GRBLHAL_VENDOR, else
#                    third_party/grblhal in the repository)
#   --table BIN      compile this table in (abbe table cgen into DIR/table/)
#   --fixed-point    the library's _q variant (as on an MCU without FPU)
#   --stock          also build the unmodified Simulator (DIR/stock/grblHAL_sim)
#
# grblHAL is GPL-3.0: its snapshots are carried unmodified in third_party/grblhal
# (third_party/README.md), nothing of it is in abbe's sources. The script extracts
# the snapshots into DIR/tree/, adds the two lines that call the plugin's init
# to the copy of the Simulator's driver_init() there, and builds
# port/grblhal/sim/CMakeLists.txt (the Simulator's own CMake project plus the
# plugin and the abbe library). Prints the simulator's path on the last line.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/../.." && pwd)"
BUILD="$REPO/build-grblhal"
VENDOR="${ABBE_GRBLHAL_VENDOR:-$REPO/third_party/grblhal}"
TABLE=""
FIXED=OFF
STOCK=0
JOBS="$(nproc 2>/dev/null || echo 2)"

while (($#)); do
    case "$1" in
    --build-dir) BUILD="$2"; shift ;;
    --vendor) VENDOR="$2"; shift ;;
    --table) TABLE="$2"; shift ;;
    --fixed-point) FIXED=ON ;;
    --stock) STOCK=1 ;;
    -h | --help) sed -n '2,19p' "$0"; exit 0 ;;
    *) echo "build_sim.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
    esac
    shift
done

core_tgz=("$VENDOR"/grblhal-core-*.tar.gz)
sim_tgz=("$VENDOR"/grblhal-simulator-*.tar.gz)
if [[ ! -f ${core_tgz[0]} || ! -f ${sim_tgz[0]} ]]; then
    echo "build_sim.sh: no grblHAL snapshots in $VENDOR (grblhal-core-*.tar.gz, grblhal-simulator-*.tar.gz)" >&2
    exit 3
fi
mkdir -p "$BUILD"
BUILD="$(cd "$BUILD" && pwd)"

# Extract once per snapshot pair (the stamp names them).
stamp="$(basename "${core_tgz[0]}") $(basename "${sim_tgz[0]}")"
TREE="$BUILD/tree"
if [[ ! -f $TREE/.abbe-stamp || "$(cat "$TREE/.abbe-stamp")" != "$stamp" ]]; then
    rm -rf "$TREE" "$BUILD/stock-tree"
    mkdir -p "$TREE"
    tar xzf "${sim_tgz[0]}" -C "$TREE"
    tar xzf "${core_tgz[0]}" -C "$TREE"
    rmdir "$TREE/Simulator/src/grbl"
    mv "$TREE/core" "$TREE/Simulator/src/grbl"
    cp -a "$TREE/Simulator" "$BUILD/stock-tree"
    # The plugin's init, called where grblHAL drivers initialise plugins: at
    # the end of driver_init(), before its version check returns.
    drv="$TREE/Simulator/src/driver.c"
    grep -q '^    return hal.version == ' "$drv" || {
        echo "build_sim.sh: driver_init()'s 'return hal.version == ...' not found in $drv" >&2
        exit 1
    }
    sed -i 's|^    return hal.version == |    extern void abbe_grblhal_init(void); /* added by abbe build_sim.sh */\n    abbe_grblhal_init();\n&|' "$drv"
    echo "$stamp" >"$TREE/.abbe-stamp"
fi

cmake_args=(-DGRBLHAL_SIM_DIR="$TREE/Simulator" -DABBE_GH_FIXED_POINT="$FIXED" -DCMAKE_BUILD_TYPE=Release)
if [[ -n $TABLE ]]; then
    ABBE="${ABBE:-$REPO/.venv/bin/abbe}"
    mkdir -p "$BUILD/table"
    "$ABBE" table cgen "$TABLE" -o "$BUILD/table" >/dev/null
    cmake_args+=(-DABBE_TABLE_DIR="$BUILD/table")
else
    cmake_args+=(-DABBE_TABLE_DIR=)
fi
cmake -S "$HERE/sim" -B "$BUILD/cmake" "${cmake_args[@]}" >/dev/null
cmake --build "$BUILD/cmake" --target grblHAL_sim -j "$JOBS" >/dev/null
if ((STOCK)); then
    cmake -S "$BUILD/stock-tree" -B "$BUILD/stock" -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build "$BUILD/stock" --target grblHAL_sim -j "$JOBS" >/dev/null
fi
echo "$BUILD/cmake/sim/grblHAL_sim"
