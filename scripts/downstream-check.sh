#!/usr/bin/env bash
# A host engine outside this repository that depends on dispmap by path and compiles its
# own G-buffer shaders with `shaderc` in its own build.rs (including dispmap's
# dispmap_gbuffer.glsl through DEP_DISPMAP_INCLUDE) must build with no .cargo/config.toml
# (after ./scripts/setup-debian.sh on Debian 12) and render. This copies the template
# scripts/downstream/ to a fresh folder outside the checkout, points it at this checkout,
# checks that no cargo config in that folder or above it could help the build, builds it
# and runs it: one 64x64 frame of the host's own 16-bit texels (the crate depends on
# dispmap with default-features = false: the lean core without file decoders), the
# host's G-buffer draw and dispmap's pass in its command buffer, with validation on,
# failing on any validation message, non-finite output or hit that differs from the
# standalone renderer's.
#
# The build reuses target/downstream (CARGO_TARGET_DIR) so that later runs are quick, and
# starts from the checkout's Cargo.lock so that it builds the versions the checkout tests.
# Runs from any folder. Needs what ./scripts/setup-debian.sh installs.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd -P)

scratch=$(mktemp -d "${TMPDIR:-/tmp}/dispmap-downstream.XXXXXX")
scratch=$(cd "$scratch" && pwd -P)
trap 'rm -rf -- "$scratch"' EXIT
case "$scratch/" in
"$root"/*)
    echo "downstream-check: $scratch is inside the checkout; set TMPDIR elsewhere" >&2
    exit 1
    ;;
esac

# The scratch crate, with the checkout's path as a TOML string.
cp -R scripts/downstream/. "$scratch/"
path=${root//\\/\\\\}
path=${path//\"/\\\"}
manifest=$(<"$scratch/Cargo.toml")
printf '%s\n' "${manifest//@DISPMAP@/"$path"}" >"$scratch/Cargo.toml"
if grep -q '@DISPMAP@' "$scratch/Cargo.toml"; then
    echo "downstream-check: placeholder left in $scratch/Cargo.toml" >&2
    exit 1
fi
if [ -f Cargo.lock ]; then
    cp Cargo.lock "$scratch/Cargo.lock"
fi

# Cargo reads .cargo/config.toml (or .cargo/config) in the folder it runs in and every
# parent, then in $CARGO_HOME. None may exist above the scratch folder; the user's
# $CARGO_HOME one is accepted with a warning unless it mentions shaderc (e.g. a
# [target.<triple>.shaderc] table that overrides shaderc-sys's build script).
cargo_home=$(cd "${CARGO_HOME:-$HOME/.cargo}" 2>/dev/null && pwd -P || echo "${CARGO_HOME:-$HOME/.cargo}")
check_home_config() {
    local file=$1
    echo "downstream-check: warning: cargo also reads $file" >&2
    if grep -qi 'shaderc' "$file"; then
        echo "downstream-check: $file mentions shaderc; it would hide the problem this checks" >&2
        exit 1
    fi
}
for file in "$cargo_home/config.toml" "$cargo_home/config"; do
    if [ -f "$file" ]; then check_home_config "$file"; fi
done
dir=$scratch
while :; do
    for file in "$dir/.cargo/config.toml" "$dir/.cargo/config"; do
        if [ -e "$file" ]; then
            case "$(cd "$dir/.cargo" && pwd -P)" in
            "$cargo_home") ;; # checked above
            *)
                echo "downstream-check: $file would apply to the scratch build; it must not exist" >&2
                exit 1
                ;;
            esac
        fi
    done
    [ "$dir" = / ] && break
    dir=$(dirname "$dir")
done

# Build and run from the scratch folder: cargo finds its config from the working folder.
export CARGO_TARGET_DIR="$root/target/downstream"
cd "$scratch"
echo "downstream-check: building $scratch (dispmap = $root, target dir $CARGO_TARGET_DIR)" >&2
cargo build
compiled=$(cargo tree --prefix none | sed 's/ (\*)$//' | sort -u | wc -l)
normal=$(cargo tree -e normal --prefix none | sed 's/ (\*)$//' | sort -u | wc -l)
core=$(cargo tree -p dispmap -e normal --prefix none | sed 's/ (\*)$//' | sort -u | wc -l)
echo "downstream-check: the downstream build compiled $compiled packages ($normal in its normal dependency graph, the scratch crate included; dispmap's: $core)"
# The host's own shaderc is built with the features the host asked for and no more:
# cargo unifies a build-dependency's features, so one that dispmap turned on would change
# how the host's build script links (docs/embedding.md).
if cargo tree -e features --prefix none -i shaderc-sys | grep -E '^shaderc-sys feature "(prefer-static-linking|build-from-source)"'; then
    echo "downstream-check: dispmap turns on a shaderc feature (above) in the host's shaderc" >&2
    exit 1
fi
# The crate depends on the lean core (default-features = false): no decoder may be in it.
if cargo tree -p dispmap -e normal,features --prefix none | grep -E '^(image|exr|png|zune-jpeg) |feature "decode"'; then
    echo "downstream-check: the scratch crate's dispmap has its file decoders (above); it must build the core without them" >&2
    exit 1
fi
cargo run --quiet
echo "downstream-check: ok"
