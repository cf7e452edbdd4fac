#!/bin/bash
# A campaign run on a lent GPU machine (torch and numpy there, no Rust, no
# network), started and collected by the device tool's `run` calls, which
# copy the working tree there (64 MiB at most) and bring back what is under
# $OUT. Here, first:
#   maturin build --release -o .whl            # abi3 wheel; /.whl/ in .git/info/exclude
#   cp campaign/RUN/model.safetensors campaign/RUN/model.json .whl/     # the --init weights
#   (the shipped model's model.json names its coarse companion: copy default_coarse.safetensors and .json beside them)
# and, if the tracked files, untracked ones git does not ignore, and .whl come to over 64 MiB
# (2026-11-28: the tracked files alone 101 MB, 21 MB without campaign/),
#   git rm -r -q --cached campaign && echo /campaign/ >> .git/info/exclude
#                                              # undo after with `git reset -q campaign`
#                                              # and deleting that line
# Then `run` (carry .whl) with
#   bash tools/gpu_run.sh start NAME [nrdepth train options, e.g. --init .whl/model.safetensors]
# which installs the wheel and starts `nrdepth train /tmp/gpu/NAME ... --device cuda
# --workers 14` detached (it outlives the call; one Rust thread per worker), and,
# in the same call (a call returns within 10 minutes of its start),
#   bash tools/gpu_run.sh collect NAME[,NAME...] SECONDS
# which waits until the runs end or SECONDS pass, stops those still going
# (`stop NAME`: the epoch under way is lost; last.pt holds the one before),
# and puts their resumable state (config, last.pt, metrics, kept epochs) in
# $OUT as one tar in 12 MB parts, NAME.tar.aa, .ab, ... (the first run's
# NAME); the run tool brings back 8 files and 64 MiB at most, the parts
# past that are lost: keep fewer epochs (--keep-every) rather than more
# parts (two runs of 13 and 14 epochs at --keep-every 2 came to 64.4 MiB). The tar
# holds every run's config and metrics first, then the last.pt files, then
# the kept epochs, so what is lost is the latest kept epochs. Two runs side by side, 8 minutes:
#   export DEVICE=cuda WORKERS=7
#   bash tools/gpu_run.sh start a ...; bash tools/gpu_run.sh start b ...; bash tools/gpu_run.sh collect a,b 480
# Committed to campaign/NAME, its config.json's "init" is set to the campaign
# path of the same weights, so that it resumes from campaign/.
#   bash tools/gpu_run.sh video x
# times the main job on the GPU instead (benchmarks/bench_video.py --only rate).
set -euo pipefail
command=$1 name=$2
shift 2
export PYTHONPATH=/tmp/site RAYON_NUM_THREADS=1  # DEVICE and WORKERS override cuda and 14 (a check on a CPU)
case $command in
start)
    [ -d /tmp/site/nrdepth ] || pip install -q --no-deps --target /tmp/site .whl/*.whl
    mkdir -p /tmp/gpu
    setsid nohup python3 -m nrdepth train "/tmp/gpu/$name" "$@" --device "${DEVICE:-cuda}" --workers "${WORKERS:-14}" --quiet \
        > "/tmp/gpu/$name.log" 2>&1 < /dev/null &
    echo $! > "/tmp/gpu/$name.pid"
    ;;
collect)
    names=${name//,/ }
    deadline=$(( $(date +%s) + $1 ))
    for run in $names; do
        while kill -0 "$(cat "/tmp/gpu/$run.pid")" 2> /dev/null && [ "$(date +%s)" -lt "$deadline" ]; do
            sleep 5
        done
    done
    for run in $names; do
        bash "$0" stop "$run"  # nothing to do for a run that ended
        tail -c 600 "/tmp/gpu/$run.log"
    done
    # One tar in 12 MB parts (each file back must be under 16 MB). Here:
    # cat NAME.tar.* > NAME.tar, check its md5sum, tar xf.
    first=${names%% *}
    (cd /tmp/gpu && for files in "config.json metrics.csv model.json" last.pt "epochs/*"; do
        for run in $names; do
            for file in $files; do ls -d "$run"/$file 2> /dev/null || true; done  # some are absent
        done
    done | tar cf "/tmp/gpu/$first.tar" -T -)
    size=$(stat -c %s "/tmp/gpu/$first.tar")
    [ "$size" -le $((64 * 1024 * 1024)) ] || echo "WARNING: the tar is $size bytes, over the 64 MiB that comes back: its tail (the last kept epochs) is lost" >&2
    mkdir -p "$OUT"
    split -b 12m "/tmp/gpu/$first.tar" "$OUT/$first.tar."
    md5sum "/tmp/gpu/$first.tar"
    ls -l "$OUT"
    ;;
stop)
    pid=$(cat "/tmp/gpu/$name.pid")
    kill -INT "$pid" 2> /dev/null || true
    for _ in $(seq 30); do kill -0 "$pid" 2> /dev/null || break; sleep 1; done
    # DataLoader workers can hold it past the interrupt: end its session (setsid) outright.
    kill -9 -- -"$pid" 2> /dev/null || true
    ;;
video)
    # The main job's speed on the GPU (frames a second at 640×480 and 1080p, default and own size), into $OUT/video.txt.
    [ -d /tmp/site/nrdepth ] || pip install -q --no-deps --target /tmp/site .whl/*.whl
    mkdir -p "$OUT"
    (cd benchmarks && RAYON_NUM_THREADS=16 python3 bench_video.py --only rate --device "${DEVICE:-cuda}") 2>&1 | tee "$OUT/video.txt"
    ;;
*)
    echo "usage: $0 start NAME [train options] | collect NAME[,NAME...] SECONDS | stop NAME | video" >&2
    exit 2
    ;;
esac
