#!/bin/sh
# Instructions per frame of the renderer's frame (demo/benches/frame_cost.rs),
# scene by scene, counted by Valgrind: a figure that does not move with the
# machine's load, unlike the bench's timings. Each scene is run twice, with
# FRAMES frames and with none; the difference over FRAMES is what a frame
# costs, the setting up of the scene and the renderer left out.
#
#   demo/benches/frame_instructions.sh            # every scene, 360 frames
#   FRAMES=60 demo/benches/frame_instructions.sh crowd
set -eu
cd "$(dirname "$0")/../.."
command -v valgrind >/dev/null || { echo "valgrind is not installed" >&2; exit 1; }
FRAMES=${FRAMES:-360}
bench=$(cargo bench -p demo --bench frame_cost --no-run --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*frame_cost[^"]*\)".*/\1/p' | tail -n 1)
[ -x "$bench" ] || { echo "could not build the frame_cost bench" >&2; exit 1; }
instructions() {
    FRAME_COST_SCENE=$1 FRAME_COST_FRAMES=$2 valgrind --tool=cachegrind --cache-sim=no \
        --cachegrind-out-file=/dev/null "$bench" 2>&1 |
        sed -n 's/.*I *refs: *\([0-9,]*\).*/\1/p' | tr -d ,
}
[ $# -gt 0 ] || set -- cube three letter_l crowd grid
for scene in "$@"; do
    idle=$(instructions "$scene" 0)
    busy=$(instructions "$scene" "$FRAMES")
    [ -n "$idle" ] && [ -n "$busy" ] || { echo "valgrind gave no count for $scene" >&2; exit 1; }
    echo "$scene: $(( (busy - idle) / FRAMES )) instructions per frame ($FRAMES frames)"
done
