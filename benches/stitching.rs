//! Stitching a 256×256×16 video from its 243 patches of 16×64×64, and a
//! 256×256×64 one from its 729 (all threads): the paper's stitch (each patch aligned to the coarse depth,
//! triangle windows) against the default one (every patch-frame of a frame
//! aligned together, Hann windows, each patch tied to the frame before) and
//! the same without the temporal tie (frames solved on their own), and the
//! default with a fifth of each frame off the surface (NaN in the coarse
//! depth: a mask, whose rows the agreement terms then sum one by one).
//!
//! Run: `cargo bench --bench stitching`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nrdepth::joint::JointStitcher;
use nrdepth::stitch::{Layout, Stitcher, Window};

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("stitching");
    g.sample_size(10);
    // 16 frames: one span of the tied solve; 64: the streaming case, where
    // each span reuses the frames the one before solved ahead.
    for frames in [16, 64] {
        let layout = Layout::new([frames, 256, 256], [16, 64, 64]).unwrap();
        let origins = layout.origins();
        let smooth = |i: usize, k: f32| ((i % 64) as f32 * 0.11 * k).sin() + ((i / 64 % 64) as f32 * 0.07 / k).cos() + (i / 4096) as f32 * 0.01;
        let patches: Vec<f32> = (0..origins.len() * 16 * 64 * 64).map(|i| smooth(i, 1.0 + (i / 65536 % 7) as f32 * 0.1)).collect();
        let coarse: Vec<f32> = (0..frames * 256 * 256).map(|i| smooth(i, 0.5)).collect();
        // Off the surface: outside a disc of radius 129 px about the centre, a fifth of each frame.
        let masked: Vec<f32> = coarse.iter().enumerate().map(|(i, &v)| if ((i / 256 % 256) as f32 - 127.5).hypot((i % 256) as f32 - 127.5) < 129.0 { v } else { f32::NAN }).collect();
        let threads = rayon::current_num_threads();
        g.bench_function(format!("paper_stitch_256x256x{frames}_{threads}_threads"), |b| {
            b.iter(|| {
                let mut s = Stitcher::new(layout, coarse.clone(), Window::Triangle).unwrap();
                s.add(&patches, &origins).unwrap();
                black_box(s.finish())
            })
        });
        // μ and ν: nrdepth.stitch's COARSE_WEIGHT and TEMPORAL_WEIGHT.
        for (name, nu, coarse) in [("default", 0.015, &coarse), ("untied", 0.0, &coarse), ("masked", 0.015, &masked)] {
            g.bench_function(format!("{name}_stitch_256x256x{frames}_{threads}_threads"), |b| {
                b.iter(|| {
                    let mut s = JointStitcher::new(layout, coarse.clone(), 0.005, nu, Window::Hann).unwrap();
                    s.add(&patches, &origins).unwrap();
                    black_box(s.finish().unwrap())
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
