//! The variant registry: every [`Pipeline`] a sweep can run and every [`Engine`] it runs on, with
//! what differs between them as methods (GPU-only, the GPU twin's [`GpuPipeline`], which reference
//! renderer draws it). The file form, the CSV and `sweep.json` use [`Pipeline::name`] and
//! [`Engine::name`]; [`Pipeline::parse`] and [`Engine::parse`] are the only string compares.
//! Adding a variant: one arm here plus its reference and GPU renderers (`runner.rs`).

use forestlod_gpu::Compaction;
use forestlod_harness::gpu_frame::GpuPipeline;

/// A registry entry with a name users write (sweep files, `--backend`, CSVs, `sweep.json`).
pub trait Registered: Copy + PartialEq + Sized + 'static {
    /// Every entry, in the order of the error messages.
    const ALL: &'static [Self];

    /// The name.
    fn name(self) -> &'static str;

    /// `expected one of a, b, c`.
    fn expected() -> String {
        let names: Vec<&str> = Self::ALL.iter().map(|v| v.name()).collect();
        format!("expected one of {}", names.join(", "))
    }

    /// The entry of a name; the error lists the valid names ([`Registered::expected`]).
    fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|v| v.name() == name)
            .ok_or_else(Self::expected)
    }
}

/// A rendering variant: ours (stable compaction on the GPU), ours with the thesis's
/// atomic-counter compaction (E§4.3; GPU backend only: the reference has one, stable, compaction,
/// equal to the atomic one as a multiset), and the two baselines of E§5.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pipeline {
    /// Ours, stable compaction.
    Ours,
    /// Ours, atomic-counter compaction (GPU only).
    OursAtomic,
    /// The per-tree culled vegetation baseline.
    Vegetation,
    /// The primitive (proxy) baseline.
    Primitive,
}

/// Which reference (CPU) renderer draws a variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceRenderer {
    /// `Prepared::render`: selection, batching, refine, draw.
    Ours,
    /// `baselines::render_vegetation`.
    Vegetation,
    /// `baselines::render_primitive`.
    Primitive,
}

impl Registered for Pipeline {
    const ALL: &'static [Self] = &[
        Pipeline::Ours,
        Pipeline::OursAtomic,
        Pipeline::Vegetation,
        Pipeline::Primitive,
    ];

    fn name(self) -> &'static str {
        match self {
            Pipeline::Ours => "ours",
            Pipeline::OursAtomic => "ours-atomic",
            Pipeline::Vegetation => "vegetation",
            Pipeline::Primitive => "primitive",
        }
    }
}

impl Pipeline {
    /// Whether it runs on the GPU backend only.
    pub fn gpu_only(self) -> bool {
        self.reference_renderer().is_none()
    }

    /// Whether it is one of ours (LOD-id images with per-LOD error maps, selection counters).
    pub fn is_ours(self) -> bool {
        matches!(self, Pipeline::Ours | Pipeline::OursAtomic)
    }

    /// Whether it is a baseline of E§5 (needs the per-tree proxies of the parameter set).
    pub fn is_baseline(self) -> bool {
        matches!(self, Pipeline::Vegetation | Pipeline::Primitive)
    }

    /// The reference renderer that draws it; `None` for GPU-only variants.
    pub fn reference_renderer(self) -> Option<ReferenceRenderer> {
        match self {
            Pipeline::Ours => Some(ReferenceRenderer::Ours),
            Pipeline::OursAtomic => None,
            Pipeline::Vegetation => Some(ReferenceRenderer::Vegetation),
            Pipeline::Primitive => Some(ReferenceRenderer::Primitive),
        }
    }

    /// What the GPU twin renders for it.
    pub fn gpu_variant(self) -> GpuPipeline {
        match self {
            Pipeline::Ours => GpuPipeline::Ours(Compaction::Stable),
            Pipeline::OursAtomic => GpuPipeline::Ours(Compaction::Atomic),
            Pipeline::Vegetation => GpuPipeline::Vegetation,
            Pipeline::Primitive => GpuPipeline::Primitive,
        }
    }
}

/// Where a variant runs: the CPU reference rasterizer or the wgpu twin (`gpu/`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Engine {
    /// The CPU reference.
    Reference,
    /// The wgpu twin.
    Gpu,
}

impl Registered for Engine {
    const ALL: &'static [Self] = &[Engine::Reference, Engine::Gpu];

    fn name(self) -> &'static str {
        match self {
            Engine::Reference => "reference",
            Engine::Gpu => "gpu",
        }
    }
}

impl Engine {
    /// The short name in plot legends (`ours ref`, `vegetation gpu`).
    pub fn short_name(self) -> &'static str {
        match self {
            Engine::Reference => "ref",
            Engine::Gpu => "gpu",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_errors_list_them() {
        for &v in Pipeline::ALL {
            assert_eq!(Pipeline::parse(v.name()), Ok(v));
        }
        for &b in Engine::ALL {
            assert_eq!(Engine::parse(b.name()), Ok(b));
        }
        assert_eq!(
            Pipeline::parse("fast").unwrap_err(),
            "expected one of ours, ours-atomic, vegetation, primitive"
        );
        assert_eq!(
            Engine::parse("cuda").unwrap_err(),
            "expected one of reference, gpu"
        );
        let gpu_only: Vec<_> = Pipeline::ALL.iter().filter(|v| v.gpu_only()).collect();
        assert_eq!(gpu_only, [&Pipeline::OursAtomic]);
    }
}
