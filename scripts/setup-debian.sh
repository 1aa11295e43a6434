#!/usr/bin/env bash
# Installs what dispmap needs on Debian 12 when it is missing:
#   mesa-vulkan-drivers     lavapipe, the CPU Vulkan driver (no GPU needed)
#   libvulkan1              the Vulkan loader
#   vulkan-validationlayers VK_LAYER_KHRONOS_validation (tests run with it on)
#   libshaderc-dev          shaderc for build.rs (with glslang-dev and spirv-tools, whose
#                           static libraries shaderc needs; see "shaderc" below)
#   pkg-config              how shaderc-sys finds shaderc (and the description below)
#   xvfb                    an X server without a screen: the viewer's test (`dispmap view`)
#   libxcursor1 libxi6 libxkbcommon-x11-0
#                           what the viewer's window library (winit) loads at run time on X11
#
# shaderc: Debian 12 ships shaderc split from glslang. Its libshaderc.so.1 leaves every
# glslang symbol undefined (and names no library that defines them), its
# libshaderc_combined.a holds shaderc's own objects only, and its shaderc.pc says
# `-lshaderc`. So any build script that uses the `shaderc` crate (dispmap's, and an
# engine's own shader build) fails to link there, with or without dispmap
# ("undefined reference: glslang::InitializeProcess()"). This script adds a complete
# description beside Debian's files, without touching them:
#   /usr/local/lib/shaderc-static/libshaderc_combined.a  a link to Debian's archive
#   /usr/local/lib/pkgconfig/shaderc.pc                  -L that folder, then
#       shaderc_combined, glslang and SPIRV-Tools, in link order
# pkg-config reads /usr/local before /usr, so shaderc-sys (the `shaderc` crate's build
# script) finds that folder through pkg-config, links shaderc statically from it and
# takes the glslang and SPIRV-Tools libraries from the .pc file: every crate's build
# script links, with no cargo config and no environment variable.
#
# As root it runs apt-get and writes those two files; otherwise it prints the exact
# commands and fails. Running it again changes nothing.
set -euo pipefail

packages=(mesa-vulkan-drivers libvulkan1 vulkan-validationlayers libshaderc-dev glslang-dev spirv-tools pkg-config xvfb libxcursor1 libxi6 libxkbcommon-x11-0)
missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done
if [ ${#missing[@]} -ne 0 ]; then
    cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ${missing[*]}"
    if [ "$(id -u)" -ne 0 ]; then
        echo "dispmap needs: ${missing[*]}" >&2
        echo "run as root:   $cmd" >&2
        echo "then run this script again (as root) to complete shaderc's link description" >&2
        exit 1
    fi
    echo "installing: ${missing[*]}" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi

# shaderc's link description (see above). Debian's folder is where libshaderc-dev put
# its archive (/usr/lib/<multiarch>).
combined=$(dpkg-query -L libshaderc-dev | grep -m 1 '/libshaderc_combined\.a$' || true)
if [ -z "$combined" ] || [ ! -f "$combined" ]; then
    echo "libshaderc-dev lists no libshaderc_combined.a: not the Debian 12 layout this script knows" >&2
    exit 1
fi
libdir=$(dirname "$combined")
if [ ! -f "$libdir/libglslang.a" ]; then
    # Not the split layout this completes: leave shaderc as the system describes it.
    exit 0
fi
# glslang 11-13 split glslang into MachineIndependent, GenericCodeGen, OGLCompiler,
# OSDependent and HLSL; a library comes before those it uses. Only those present.
libs="-lshaderc_combined"
for lib in SPIRV glslang MachineIndependent GenericCodeGen OGLCompiler OSDependent HLSL SPIRV-Tools-opt SPIRV-Tools; do
    if [ -f "$libdir/lib$lib.a" ]; then
        libs="$libs -l$lib"
    fi
done
folder=/usr/local/lib/shaderc-static
pc=/usr/local/lib/pkgconfig/shaderc.pc
version=$(dpkg-query -W -f='${Version}' libshaderc-dev)
description="# Written by dispmap's scripts/setup-debian.sh: Debian 12's shaderc.pc (-lshaderc) names
# a libshaderc.so.1 whose glslang symbols are undefined. This one links Debian's
# libshaderc_combined.a (linked from $folder) with the glslang and SPIRV-Tools static
# libraries it needs. Delete this file and $folder to undo.
prefix=/usr
libdir=$libdir
includedir=\${prefix}/include

Name: shaderc
Description: shaderc (Debian's libshaderc-dev $version) linked statically with glslang and SPIRV-Tools
Version: $version
Libs: -L$folder -L\${libdir} $libs
Cflags: -I\${includedir}"
if [ "$(readlink "$folder/libshaderc_combined.a" 2>/dev/null || true)" = "$combined" ] &&
    [ "$(cat "$pc" 2>/dev/null || true)" = "$description" ]; then
    exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
    echo "dispmap needs shaderc's link description ($pc, see this script's comments)" >&2
    echo "run this script as root" >&2
    exit 1
fi
echo "writing $pc and $folder/libshaderc_combined.a -> $combined" >&2
mkdir -p "$folder" "$(dirname "$pc")"
ln -sfn "$combined" "$folder/libshaderc_combined.a"
printf '%s\n' "$description" >"$pc.tmp"
mv "$pc.tmp" "$pc"
