//! Region decodes of the vectors (spec §10.3.1, §11.7): boxes chosen from each vector's own
//! tile table so that each pins one rule a decoder's author could guess wrong — the closed
//! box test at a tile's low and high faces, the re-basing of spatial regions when region 0
//! drops out, an empty selection, a fault in a tile the box leaves out, and the explicit
//! profile's tile boxes in the layer's grid.
//!
//! Each box is checked here against the rule it pins: a face box must select a tile that a
//! strict (open) test would not, so the vector tells the two readings apart.

use salvq::RegionBox;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::limits::Limits;
use salvq_bitstream::tiles::TileTable;
use salvq_encoder::writers::surgery;

/// One region decode of a vector.
pub struct RegionCase {
    pub rate: u8,
    pub region: RegionBox,
    /// What it pins, one line.
    pub pins: &'static str,
}

/// Where a stream's tiles are: their table, and the grid their voxels are in.
struct TileGrid {
    tiles: TileTable,
    origin: [f32; 3],
    voxel_size: f32,
}

impl TileGrid {
    fn world(&self, t: usize) -> [f64; 6] {
        self.tiles.world_box(t, self.origin, self.voxel_size)
    }

    fn select(&self, b: RegionBox) -> Vec<usize> {
        let s = self
            .tiles
            .select(self.origin, self.voxel_size, Some(b), None);
        (0..s.len()).filter(|&t| s[t]).collect()
    }

    /// The tiles a strict reading (`lo < max` and `min < hi`) would select.
    fn select_open(&self, b: RegionBox) -> Vec<usize> {
        (0..self.tiles.len())
            .filter(|&t| {
                let w = self.world(t);
                (0..3).all(|a| w[a] < b.max()[a] && b.min()[a] < w[3 + a])
            })
            .collect()
    }

    /// Boxes inside tile `t`'s box: points half a voxel in from its corners and its centre,
    /// then the box itself.
    fn boxes_in(&self, t: usize) -> Vec<RegionBox> {
        let w = self.world(t);
        let half = f64::from(self.voxel_size) / 2.0;
        let mut points = vec![[
            (w[0] + w[3]) / 2.0,
            (w[1] + w[4]) / 2.0,
            (w[2] + w[5]) / 2.0,
        ]];
        for corner in 0..8 {
            points.push(std::array::from_fn(|a| {
                if corner >> a & 1 == 0 {
                    w[a] + half
                } else {
                    w[3 + a] - half
                }
            }));
        }
        let mut boxes: Vec<RegionBox> = points
            .into_iter()
            .map(|p| RegionBox::new(p, p).expect("a point is a box"))
            .collect();
        boxes.push(RegionBox::from_array(w).expect("a tile box is a box"));
        boxes
    }

    /// A box inside tile `t`'s box that selects `t` alone, if one of [`Self::boxes_in`] does.
    fn point_in(&self, t: usize) -> Option<RegionBox> {
        self.boxes_in(t)
            .into_iter()
            .find(|&b| self.select(b) == [t])
    }
}

fn anchors_grid(stream: &[u8]) -> TileGrid {
    let chunks = surgery::chunks(stream).expect("a generated stream frames");
    let payload = |tag: ChunkTag| {
        chunks
            .iter()
            .find(|(t, _)| *t == tag)
            .map(|(_, p)| p.clone())
            .expect("the chunk is in a generated stream")
    };
    let head = Preflight::parse(&payload(ChunkTag::HEAD), &Limits::default())
        .expect("a generated HEAD parses");
    let tiles = TileTable::parse(&payload(ChunkTag::TILS), head.dims.anchors, head.coord_bits)
        .expect("a generated TILS parses");
    TileGrid {
        tiles,
        origin: head.origin,
        voxel_size: head.voxel_size,
    }
}

fn explicit_grid(stream: &[u8], rate: u8) -> TileGrid {
    let d = salvq::Decoder::builder()
        .limits(Limits::default())
        .rate(Some(rate))
        .build()
        .decode(stream)
        .and_then(salvq::Scene::try_into_gaussians)
        .expect("a valid explicit vector decodes");
    TileGrid {
        tiles: d.tiles,
        origin: d.header.origin,
        voxel_size: d.layer.voxel_size,
    }
}

/// A slab against tile `t`'s face on `axis` (its low face when `low`), spanning the tile on
/// the other axes and half a voxel deep outside it.
fn slab(g: &TileGrid, t: usize, axis: usize, low: bool) -> RegionBox {
    let w = g.world(t);
    let (mut min, mut max) = ([w[0], w[1], w[2]], [w[3], w[4], w[5]]);
    let half = f64::from(g.voxel_size) / 2.0;
    if low {
        (min[axis], max[axis]) = (w[axis] - half, w[axis]);
    } else {
        (min[axis], max[axis]) = (w[3 + axis], w[3 + axis] + half);
    }
    RegionBox::new(min, max).expect("a slab is a box")
}

/// The first face slab (over tiles and axes) that selects a tile the strict reading leaves
/// out.
fn face_case(g: &TileGrid, low: bool) -> RegionBox {
    (0..g.tiles.len())
        .flat_map(|t| (0..3).map(move |a| (t, a)))
        .map(|(t, a)| slab(g, t, a, low))
        .find(|&b| g.select(b) != g.select_open(b))
        .expect("some face slab tells the closed test from the open one")
}

/// The region decodes of the vector `name` (none for most vectors).
pub fn region_cases(name: &str, stream: &[u8]) -> Vec<RegionCase> {
    match name {
        "tiles-regions" => tiles_regions_cases(stream),
        "x-ans-lowest-tile-reported" => {
            let g = anchors_grid(stream);
            vec![RegionCase {
                rate: 0,
                region: g.point_in(0).expect("a point selects tile 0 alone"),
                pins: "the faults in tile 1's AOFF body and the last tile's AFEA body are not \
                       decoded: a region decode of tile 0 succeeds",
            }]
        }
        "g-sh0" => {
            let g = explicit_grid(stream, 0);
            vec![RegionCase {
                rate: 0,
                region: g.point_in(1).expect("a point selects tile 1 alone"),
                pins: "explicit profile: tile boxes in the layer's grid (GHED origin, GLAY \
                       voxel_size); tile 1 alone",
            }]
        }
        _ => Vec::new(),
    }
}

fn tiles_regions_cases(stream: &[u8]) -> Vec<RegionCase> {
    let g = anchors_grid(stream);
    let model = salvq::decode(stream)
        .and_then(salvq::Scene::try_into_anchors)
        .expect("a valid vector decodes");
    let starts: Vec<usize> = model
        .quant_feat
        .region_starts()
        .iter()
        .map(|&s| s as usize)
        .collect();
    assert!(starts.len() >= 3, "three feature regions");
    // A box whose tiles all lie past region 0, with one tile straddling a later boundary,
    // so region 0 drops out and the next one becomes region 0 with a later one after it.
    let straddles = |t: usize, s: usize| {
        let r = g.tiles.range(t);
        r.start < s && s < r.end
    };
    let late = (0..g.tiles.len())
        .filter(|&t| starts[2..].iter().any(|&s| straddles(t, s)))
        .flat_map(|t| g.boxes_in(t))
        .find(|&b| {
            let sel = g.select(b);
            sel.iter().all(|&t| g.tiles.range(t).start >= starts[1])
                && sel
                    .iter()
                    .any(|&t| starts[2..].iter().any(|&s| straddles(t, s)))
        })
        .expect("a tile straddling a later region boundary, away from region 0");
    let far = {
        let o = g.origin.map(|x| f64::from(x) - 1.0e3);
        RegionBox::new(o, o).expect("a point is a box")
    };
    assert!(g.select(far).is_empty());
    vec![
        RegionCase {
            rate: 0,
            region: face_case(&g, true),
            pins: "the box test is closed: a slab touching a tile's low face selects it",
        },
        RegionCase {
            rate: 0,
            region: face_case(&g, false),
            pins: "the box test is closed and a tile's world box ends at (max + 1) voxels: a \
                   slab touching its high face selects it",
        },
        RegionCase {
            rate: 0,
            region: late,
            pins: "spatial regions re-based: region 0 has no selected anchor and drops out, \
                   the next region becomes region 0, a straddled boundary gets a new start",
        },
        RegionCase {
            rate: 0,
            region: far,
            pins: "no tile selected: every shared tensor, per-anchor tensors of 0 rows, one \
                   region per group",
        },
    ]
}

/// An anchors-profile stream's tile table.
pub fn anchors_tiles(stream: &[u8]) -> TileTable {
    anchors_grid(stream).tiles
}

/// The tiles `region` selects in `stream` at `rate` (for the manifest).
pub fn selected_tiles(stream: &[u8], rate: u8, region: RegionBox) -> Vec<u32> {
    let g = if salvq_bitstream::container::is_explicit(stream) {
        explicit_grid(stream, rate)
    } else {
        anchors_grid(stream)
    };
    g.select(region).into_iter().map(|t| t as u32).collect()
}
