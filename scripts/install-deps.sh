#!/usr/bin/env bash
# Installs everything lambert needs on Debian 12 (apt-get). Safe to run again: it skips what is there.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git
  libeigen3-dev        # dense linear algebra, Krylov solvers
  libopenmesh-dev      # polygon mesh (patches, adjacency)
  libcgal-dev          # geometry: convex hulls, mesh processing
  libboost-dev         # Boost.Polygon (header-only): daylight sky clipping (CGAL pulls it in anyway)
  libembree-dev        # ray tracing for visibility
  libpolyclipping-dev  # Clipper: 2D Boolean operations (union of projected occluders, exact visibility)
  libvtk9-dev          # .vtu output for ParaView
  libtbb-dev           # threads
  libcli11-dev         # command line
  nlohmann-json3-dev   # --materials and --stats JSON
  libfmt-dev           # formatting
  libgtest-dev libgmock-dev libbenchmark-dev  # tests and benchmarks
  paraview xvfb xauth  # the ParaView check (pvbatch under xvfb-run)
  python3 python3-matplotlib  # the accuracy study's plots (scripts/plot_study.py, run with /usr/bin/python3)
)
PV_PYTHON_DIR=${LAMBERT_PARAVIEW_PYTHON_DIR:-/opt/lambert/paraview-python}

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  # python3-paraview conflicts with python3-vtk9 (needed by libvtk9-dev): never install it through apt.
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" python3-paraview- >/dev/null
fi

# ParaView's Python modules (package python3-paraview) are unpacked into a private directory instead,
# so pvbatch works while libvtk9-dev stays installed. Tests pass this directory as PYTHONPATH.
if [ ! -d "$PV_PYTHON_DIR/usr/lib/python3/dist-packages/paraview" ]; then
  echo "install-deps: unpacking python3-paraview into $PV_PYTHON_DIR" >&2
  tmp=$(mktemp -d)
  chmod 777 "$tmp"
  ( cd "$tmp" && { apt-get download python3-paraview >/dev/null 2>&1 || { $SUDO apt-get update -qq && apt-get download python3-paraview >/dev/null; }; } )
  $SUDO mkdir -p "$PV_PYTHON_DIR"
  $SUDO dpkg -x "$tmp"/python3-paraview_*.deb "$PV_PYTHON_DIR"
  rm -rf "$tmp"
fi
echo "install-deps: all dependencies present" >&2
