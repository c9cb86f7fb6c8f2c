#!/usr/bin/env bash
# Installs every build and run dependency of ehlsim from Debian's packages.
# Idempotent; run as root (or with sudo available) on Debian 12.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  ccache                  # compiler cache: CI rebuilds a clean clone (CMakeLists.txt)
  libfftw3-dev            # FFT convolution of the deformation integral
  liblapack-dev           # dense solves of the local Newton step (reference LAPACK)
  libtomlplusplus-dev     # configuration files
  libcli11-dev            # command line
  libfmt-dev              # formatting
  zlib1g-dev              # CRC-32 of the checkpoints
  libnetcdf-dev netcdf-bin  # fields.nc output (netcdf-bin: ncdump, for inspection and the reproducibility tests)
  nlohmann-json3-dev      # run.json
  libgtest-dev libgmock-dev libbenchmark-dev  # tests and benchmarks
  python3-matplotlib python3-numpy            # figures (Debian's own python3)
  python3-xarray python3-netcdf4              # reading fields.nc in Python (README; the Xarray tests)
  clang-format            # the layout check of .ci/run
  paraview python3-paraview xvfb xauth  # the headless ParaView test of fields.nc (pvbatch under xvfb-run)
  clang libclang-rt-14-dev libomp-dev  # the libFuzzer targets of fuzz/ (clang, its sanitizer runtimes, OpenMP)
  llvm                    # llvm-symbolizer: file and line in sanitizer reports
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
