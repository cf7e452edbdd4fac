//! Synthesis of one 16-frame 64×64 clip (single thread, reused synthesizer)
//! and of a batch of 64 clips (rayon over clips).
//!
//! Run: `cargo bench --bench synthesis`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nrdepth::synthesis::clip_len;
use nrdepth::{synthesize_batch, SurfaceConfig, Synthesizer};

fn bench(c: &mut Criterion) {
    let (frames, grid) = (16, 64);
    let config = SurfaceConfig::default();
    let params: Vec<_> = (0..64).map(|s| config.sample(s).unwrap()).collect();

    let mut group = c.benchmark_group("synthesis");
    group.throughput(Throughput::Elements(1));
    let mut synth = Synthesizer::new(grid);
    let mut out = vec![0.0f32; clip_len(frames, grid)];
    let mut i = 0;
    group.bench_function(BenchmarkId::new("clip_16x64x64", "one thread"), |b| {
        b.iter(|| {
            i = (i + 1) % params.len();
            synth.synthesize_into(black_box(&params[i]), frames, &mut out).unwrap();
        })
    });
    group.throughput(Throughput::Elements(params.len() as u64));
    let mut batch = vec![0.0f32; params.len() * clip_len(frames, grid)];
    group.bench_function(BenchmarkId::new("batch_64_clips", format!("{} threads", rayon::current_num_threads())), |b| {
        b.iter(|| synthesize_batch(black_box(&params), frames, grid, &mut batch).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
