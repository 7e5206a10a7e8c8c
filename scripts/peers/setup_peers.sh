#!/bin/sh
# The open peers of `livedic bench peers`, set up outside livedic (never its dependencies).
#
# usage: scripts/peers/setup_peers.sh DIR OPENCORR_SOURCE
#   DIR              where the peers go: DIR/sundic-venv (SUN-DIC, PyPI sun-dic) and DIR/opencorr_icgn1
#   OPENCORR_SOURCE  a checkout of OpenCorr (GitHub vincentjzy/OpenCorr); its src/ is compiled
# needs: python3 (venv, pip), g++ with OpenMP, Debian's libeigen3-dev libfftw3-dev libopencv-dev
# then:  livedic bench peers --sundic-python DIR/sundic-venv/bin/python --opencorr-bin DIR/opencorr_icgn1
set -e
[ $# -eq 2 ] || { echo "usage: $0 DIR OPENCORR_SOURCE" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$1"
dir=$(cd "$1" && pwd)
src=$(cd "$2" && pwd)/src
[ -f "$src/oc_icgn.cpp" ] || { echo "$2 is not an OpenCorr checkout (no src/oc_icgn.cpp)" >&2; exit 2; }

python3 -m venv "$dir/sundic-venv"
"$dir/sundic-venv/bin/python" -m pip install -q sun-dic

# Only the modules FFT-CC + IC-GN need: the rest (SIFT, nearest neighbours) wants a newer nanoflann than Debian's.
flags="-O3 -std=c++17 -fopenmp -w -I $src -I /usr/include/eigen3 -I /usr/include/eigen3/Eigen -I /usr/include/opencv4"
mkdir -p "$dir/obj"
for module in cubic_bspline deformation dic fftcc gradient icgn image poi point subset; do
  [ -f "$src/oc_$module.cpp" ] && g++ $flags -c "$src/oc_$module.cpp" -o "$dir/obj/oc_$module.o" &
done
wait
g++ $flags "$here/opencorr_icgn1.cpp" "$dir"/obj/*.o -o "$dir/opencorr_icgn1" \
  -lopencv_core -lopencv_imgcodecs -lopencv_imgproc -lfftw3f -lfftw3 -lgomp
echo "livedic bench peers --sundic-python $dir/sundic-venv/bin/python --opencorr-bin $dir/opencorr_icgn1"
