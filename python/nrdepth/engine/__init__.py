"""The data engine: deforming surfaces from FFT coloured noise
(:mod:`.surface`), rendered with their true depth (:mod:`.render`, the
Rust rasteriser and ray caster), cut into training clips
(:mod:`.generate`), written as HDF5 shards (:mod:`.dataset`), and pictured
(:mod:`.preview`). docs/data-engine.md has the method."""
