//! Time the default clip generator on one thread and fingerprint its output.
//!
//! `cargo run --release --example time_clips -- [CLIPS=200] [phong|gouraud]`
//! prints ms per clip and an FNV-1a hash of every video byte and depth bit of
//! clips 0 .. CLIPS (seed 0): a speed change to the generator must leave the
//! hash as it was. Compare timings of two builds by interleaving their runs.

use nrdepth::generate::{ClipWorker, GeneratorConfig};
use nrdepth::raster::Shading;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: u64 = args.next().map(|s| s.parse().expect("CLIPS: a number")).unwrap_or(200);
    let shading = args.next().map(|s| Shading::from_name(&s).expect("phong or gouraud")).unwrap_or(Shading::Phong);
    let config = GeneratorConfig { shading, ..GeneratorConfig::default() };
    let len = config.clip_pixels();
    let (mut video, mut depth) = (vec![0u8; len], vec![0f32; len]);
    let mut worker = ClipWorker::new(&config);
    let (mut redraws, mut fingerprint) = (0, 0xcbf2_9ce4_8422_2325u64);
    let start = std::time::Instant::now();
    for i in 0..n {
        redraws += worker.clip(&config, None, 0, i, &mut video, &mut depth).expect("default config").redraws;
        for word in video.iter().map(|&v| v as u64).chain(depth.iter().map(|d| d.to_bits() as u64)) {
            fingerprint = (fingerprint ^ word).wrapping_mul(0x100_0000_01b3);
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    println!("{n} clips ({}) in {seconds:.3} s: {:.2} ms/clip, redraws {redraws}, fingerprint {fingerprint:016x}", shading.name(), seconds * 1e3 / n as f64);
}
