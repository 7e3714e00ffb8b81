//! The header and model fields a rule constrains, spelled as the spec's syntax tables spell
//! them (Table 1-4, §3.2, §3.4).

/// A header or model dimension whose value a rule constrains (spec §1.4, Table 1-4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// `file_flags`.
    FileFlags,
    /// `head_flags`.
    HeadFlags,
    /// `anchor_count`.
    AnchorCount,
    /// `feat_dim`.
    FeatDim,
    /// `offset_count`.
    OffsetCount,
    /// `scaling_dim`.
    ScalingDim,
    /// `rate_count`.
    RateCount,
    /// `coord_bits`.
    CoordBits,
    /// `voxel_size`.
    VoxelSize,
    /// `origin`.
    Origin,
    /// `grid_channels`.
    GridChannels,
    /// `levels_3d`.
    Levels3d,
    /// `levels_2d`.
    Levels2d,
    /// `log2_size_3d`.
    Log2Size3d,
    /// `log2_size_2d`.
    Log2Size2d,
    /// `resolution_3d`.
    Resolution3d,
    /// `resolution_2d`.
    Resolution2d,
    /// `context_input_dim`.
    ContextInputDim,
    /// `context_hidden`.
    ContextHidden,
    /// `scaffold_hidden`.
    ScaffoldHidden,
    /// `view_dims`.
    ViewDims,
    /// `rate`.
    CodedRate,
    /// `rate_mask`.
    RateMask,
    /// `feat_lattice`.
    FeatLattice,
    /// `scaling_lattice`.
    ScalingLattice,
    /// `feat_regions`.
    FeatRegions,
    /// `scaling_regions`.
    ScalingRegions,
    /// `region_start`.
    RegionStart,
    /// `tile_count`.
    TileCount,
    /// `tile_anchors`.
    TileAnchors,
    /// `cell_level`.
    TileCellLevel,
    /// `cell`.
    TileCell,
    /// `w0_frac_bits`.
    W0FracBits,
    /// `shift0`.
    Shift0,
    /// `w1_frac_bits`.
    W1FracBits,
    /// `scaffold_precision`.
    ScaffoldPrecision,
    /// `context_precision`.
    ContextPrecision,
    /// `gaussian_count`.
    GaussianCount,
    /// `sh_degree`.
    ShDegree,
    /// `pred_level`.
    PredLevel,
    /// `scale_table`.
    ScaleTable,
    /// `rotation_freq`.
    RotationFreq,
    /// `predict`.
    PredictFlag,
    /// `refine`.
    Refine,
    /// `rest_count_freq`.
    RestCountFreq,
    /// `factor`.
    Factor,
}

impl Field {
    /// The field's name as the spec's syntax tables spell it.
    pub fn spec_name(self) -> &'static str {
        match self {
            Field::GaussianCount => "gaussian_count",
            Field::ShDegree => "sh_degree",
            Field::PredLevel => "pred_level",
            Field::ScaleTable => "scale_table",
            Field::RotationFreq => "rotation_freq",
            Field::PredictFlag => "predict",
            Field::Refine => "refine",
            Field::RestCountFreq => "rest_count_freq",
            Field::Factor => "factor",
            Field::FileFlags => "file_flags",
            Field::HeadFlags => "head_flags",
            Field::AnchorCount => "anchor_count",
            Field::FeatDim => "feat_dim",
            Field::OffsetCount => "offset_count",
            Field::ScalingDim => "scaling_dim",
            Field::RateCount => "rate_count",
            Field::CoordBits => "coord_bits",
            Field::VoxelSize => "voxel_size",
            Field::Origin => "origin",
            Field::GridChannels => "grid_channels",
            Field::Levels3d => "levels_3d",
            Field::Levels2d => "levels_2d",
            Field::Log2Size3d => "log2_size_3d",
            Field::Log2Size2d => "log2_size_2d",
            Field::Resolution3d => "resolution_3d",
            Field::Resolution2d => "resolution_2d",
            Field::ContextInputDim => "context_input_dim",
            Field::ContextHidden => "context_hidden",
            Field::ScaffoldHidden => "scaffold_hidden",
            Field::ViewDims => "view_dims",
            Field::CodedRate => "rate",
            Field::RateMask => "rate_mask",
            Field::FeatLattice => "feat_lattice",
            Field::ScalingLattice => "scaling_lattice",
            Field::FeatRegions => "feat_regions",
            Field::ScalingRegions => "scaling_regions",
            Field::RegionStart => "region_start",
            Field::TileCount => "tile_count",
            Field::TileAnchors => "tile_anchors",
            Field::TileCellLevel => "cell_level",
            Field::TileCell => "cell",
            Field::W0FracBits => "w0_frac_bits",
            Field::Shift0 => "shift0",
            Field::ScaffoldPrecision => "scaffold_precision",
            Field::ContextPrecision => "context_precision",
            Field::W1FracBits => "w1_frac_bits",
        }
    }
}
