#!/usr/bin/env bash
# Installs what dispmap needs on Debian 12 when it is missing:
#   mesa-vulkan-drivers     lavapipe, the CPU Vulkan driver (no GPU needed)
#   libvulkan1              the Vulkan loader
#   vulkan-validationlayers VK_LAYER_KHRONOS_validation (tests run with it on)
#   libshaderc-dev          shaderc for build.rs (pulls glslang-dev and spirv-tools,
#                           whose static libraries build-support/shaderc-link links)
#   xvfb                    an X server without a screen: the viewer's test (`dispmap view`)
#   libxcursor1 libxi6 libxkbcommon-x11-0
#                           what the viewer's window library (winit) loads at run time on X11
# As root it runs apt-get; otherwise it prints the exact command and fails.
set -euo pipefail

packages=(mesa-vulkan-drivers libvulkan1 vulkan-validationlayers libshaderc-dev glslang-dev spirv-tools xvfb libxcursor1 libxi6 libxkbcommon-x11-0)
missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done
if [ ${#missing[@]} -eq 0 ]; then
    exit 0
fi
cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ${missing[*]}"
if [ "$(id -u)" -ne 0 ]; then
    echo "dispmap needs: ${missing[*]}" >&2
    echo "run as root:   $cmd" >&2
    exit 1
fi
echo "installing: ${missing[*]}" >&2
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
