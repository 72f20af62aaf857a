//! The brute-force cone oracle: every triangle, the exact test. The ground truth every cone
//! traversal must equal bit for bit (`tests/cone.rs`).

use super::{
    offer, walk, ConeBatch, ConeCounts, ConeHits, ConeTracer, Nearest, Prepared, Query, Walker,
};
use crate::error::Result;
use crate::scene::{Scene, Stamp, TriangleSoup};
use crate::tracer::Stats;

/// Every triangle against every cone.
#[derive(Debug, Default)]
pub struct Oracle {
    stamp: Stamp,
}

struct All;

impl Walker for All {
    type Scratch = ();
    fn walk(
        &self,
        soup: &TriangleSoup,
        cone: &Prepared,
        list: &mut Nearest,
        count_only: bool,
        _: &mut (),
        c: &mut ConeCounts,
    ) {
        for id in 0..soup.len() as u32 {
            offer(soup, id, cone, list, count_only, c);
        }
    }
}

impl ConeTracer for Oracle {
    fn name(&self) -> String {
        "oracle".into()
    }
    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        self.stamp = scene.stamp();
        Ok(Stats::default())
    }
    fn trace(
        &self,
        scene: &Scene,
        cones: &ConeBatch,
        q: &Query,
        out: &mut ConeHits,
    ) -> Result<Stats> {
        self.stamp.check(scene, "cone oracle")?;
        Ok(walk(&All, scene.triangles(), cones, q, out))
    }
    fn bytes(&self) -> usize {
        0
    }
}
