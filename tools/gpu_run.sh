#!/bin/bash
# A campaign run on a lent GPU machine (torch and numpy there, no Rust, no
# network), started and collected by the device tool's `run` calls, which
# copy the working tree there (64 MiB at most) and bring back what is under
# $OUT. Here, first:
#   maturin build --release -o .whl            # abi3 wheel; /.whl/ in .git/info/exclude
#   cp campaign/RUN/model.safetensors campaign/RUN/model.json .whl/     # the --init weights
#   git rm -r -q --cached campaign && echo /campaign/ >> .git/info/exclude
#                                              # campaign/ is over 64 MiB; undo after with
#                                              # `git reset -q campaign` and deleting that line
# Then `run` (carry .whl) with
#   bash tools/gpu_run.sh start NAME [nrdepth train options, e.g. --init .whl/model.safetensors]
# which installs the wheel and starts `nrdepth train /tmp/gpu/NAME ... --device cuda
# --workers 14` detached (it outlives the call; one Rust thread per worker), and,
# within 30 s of each call's end so that the machine stays warm,
#   bash tools/gpu_run.sh collect NAME SECONDS
# which waits until the run ends or SECONDS pass and puts its resumable state
# (config, last.pt, metrics, best weights, kept epochs) in $OUT as one tar in
# 12 MB parts, NAME.tar.aa, .ab, ...; over 8 parts, collect again in a
# later call after moving some epochs away.
#   bash tools/gpu_run.sh stop NAME
# interrupts a run that would outlast the lease (the epoch under way is lost;
# last.pt holds the one before), so that collect can follow at once.
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
    deadline=$(( $(date +%s) + $1 ))
    while kill -0 "$(cat "/tmp/gpu/$name.pid")" 2> /dev/null && [ "$(date +%s)" -lt "$deadline" ]; do
        sleep 5
    done
    tail -c 600 "/tmp/gpu/$name.log"
    # The run tool brings back a few files a call, each under ~16 MB: one tar
    # (with --keep-every's weights, to score along the curve) in 12 MB parts.
    # Here: cat NAME.tar.* > NAME.tar, check its md5sum, tar xf.
    (cd /tmp/gpu && ls -d "$name"/config.json "$name"/last.pt "$name"/metrics.csv "$name"/model.json \
        "$name"/model.safetensors "$name"/epochs 2> /dev/null | tar cf "/tmp/gpu/$name.tar" -T -) || true  # ls: some are absent
    mkdir -p "$OUT"
    split -b 12m "/tmp/gpu/$name.tar" "$OUT/$name.tar."
    md5sum "/tmp/gpu/$name.tar"
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
    echo "usage: $0 start NAME [train options] | collect NAME SECONDS | stop NAME | video" >&2
    exit 2
    ;;
esac
