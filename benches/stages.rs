//! Per-stage costs of clip generation on one thread, plus end-to-end clips.
//!
//! Run: `cargo bench --bench stages`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nrdepth::bvh::Bvh;
use nrdepth::generate::{generate_clips, noisy_u8, ClipWorker, GeneratorConfig};
use nrdepth::geometry::{View, CAMERA_Z};
use nrdepth::mesh::grid_triangles;
use nrdepth::raster::{Frame, Light, LightKind, Material, Rasterizer, Scene, Shading, Texture};
use nrdepth::textures::{procedural, TextureFamily, FAMILIES};
use nrdepth::{synthesize, SurfaceConfig};

fn still_surface(grid: usize) -> Vec<[f32; 3]> {
    let mut p = SurfaceConfig::default().sample(1).unwrap();
    p.rotation = [0.0; 3];
    p.rotation_rate = [0.0; 3];
    p.drift = [0.0; 3];
    synthesize(&p, 1, grid).unwrap().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

fn bench(c: &mut Criterion) {
    let grid = 64;
    let vertices = still_surface(grid);
    let triangles: Vec<[u32; 3]> = grid_triangles(grid as i64).unwrap().chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let view = View::new(64, 64, [-0.5, -0.5, 0.5, 0.5], CAMERA_Z).unwrap();
    let mut depth = vec![0.0f32; 64 * 64];

    let mut g = c.benchmark_group("stages");
    g.bench_function("bvh_grid_build_refit_cast_64x64_8k_tris", |b| {
        b.iter(|| {
            let mut bvh = Bvh::for_grid(grid);
            bvh.refit(&vertices, &triangles);
            bvh.depth_into(&vertices, &triangles, &view, &mut depth);
            black_box(&depth);
        })
    });
    let mut bvh = Bvh::for_grid(grid);
    g.bench_function("bvh_refit_cast_64x64_8k_tris", |b| {
        b.iter(|| {
            bvh.refit(&vertices, &triangles);
            bvh.depth_into(&vertices, &triangles, &view, &mut depth);
            black_box(&depth);
        })
    });
    g.bench_function("bvh_generic_build_8k_tris", |b| b.iter(|| black_box(Bvh::build(&vertices, &triangles))));

    let uv: Vec<[f32; 2]> = (0..grid * grid).map(|i| [(i % grid) as f32 / 63.0, 1.0 - (i / grid) as f32 / 63.0]).collect();
    let mut texture = Texture::default();
    procedural(TextureFamily::Fractal, 3, 256, &mut texture);
    let lights = [
        Light { kind: LightKind::Directional, vector: [0.3, 0.2, 1.0], intensity: 0.6 },
        Light { kind: LightKind::Point, vector: [2.0, -1.0, 3.0], intensity: 0.4 },
    ];
    let material = Material { ambient: 0.1, diffuse: 0.8, specular: 0.3, shininess: 20.0 };
    let mut rasterizer = Rasterizer::default();
    let mut frame = Frame::default();
    for shading in [Shading::Phong, Shading::Gouraud] {
        let scene = Scene { view, supersample: 2, lights: &lights, material, texture: &texture, shading };
        g.bench_function(format!("raster_64x64_ss2_8k_tris_2_lights_{}", shading.name()), |b| {
            b.iter(|| rasterizer.render_into(&vertices, &triangles, &uv, &scene, &mut frame))
        });
    }
    let (image, mut noisy) = ((0..64 * 64).map(|k| (k % 97) as f32 / 97.0).collect::<Vec<f32>>(), vec![0u8; 64 * 64]);
    g.bench_function("noise_quantise_64x64", |b| {
        b.iter(|| {
            noisy_u8(black_box(&image), 0.02, 7, 3, &mut noisy);
            black_box(&noisy);
        })
    });
    let mut tex = Texture::default();
    for family in FAMILIES {
        g.bench_function(format!("texture_{}_256", family.name()), |b| b.iter(|| procedural(family, 5, 256, &mut tex)));
    }

    for shading in [Shading::Phong, Shading::Gouraud] {
        let config = GeneratorConfig { shading, ..GeneratorConfig::default() };
        let len = config.clip_pixels();
        let (mut video, mut clip_depth) = (vec![0u8; len], vec![0f32; len]);
        let mut worker = ClipWorker::new(&config);
        let mut index = 0;
        g.throughput(Throughput::Elements(1));
        g.bench_function(format!("clip_16x64x64_one_thread_{}", shading.name()), |b| {
            b.iter(|| {
                index += 1;
                worker.clip(&config, None, 0, index, &mut video, &mut clip_depth).unwrap()
            })
        });
        let n = 32;
        let (mut video, mut clip_depth) = (vec![0u8; n * len], vec![0f32; n * len]);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_function(format!("clips_32_{}_threads_{}", rayon::current_num_threads(), shading.name()), |b| {
            b.iter(|| generate_clips(&config, None, 0, 0, n, &mut video, &mut clip_depth).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
