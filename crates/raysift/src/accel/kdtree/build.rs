//! The event-sorted O(N log N) SAH build (Wald & Havran 2006, §4): see the module doc of
//! [`super`] for the rules; this file is the sweep and the in-order split of the event lists.

use super::{BuildConfig, KdTree, Node, MAX_INDEX};
use crate::error::{Error, Result};
use crate::geom::Aabb;
use crate::scene::TriangleSoup;
use rayon::prelude::*;
use std::cmp::Ordering;

/// Event kinds, in the order events at one position are swept (Wald & Havran: ends, then
/// planar, then starts).
const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

/// One event of a triangle's (cell-clipped) box on one axis: 12 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Event {
    pos: f32,
    tri: u32,
    kind: u8,
}

impl Event {
    fn new(pos: f32, tri: u32, kind: u8) -> Self {
        // `+ 0.0` turns -0.0 into +0.0, so equal positions are one group in the sweep.
        Self {
            pos: pos + 0.0,
            tri,
            kind,
        }
    }

    /// Sweep order: position, kind, triangle id (the id makes the build deterministic).
    fn cmp(&self, o: &Self) -> Ordering {
        self.pos
            .total_cmp(&o.pos)
            .then(self.kind.cmp(&o.kind))
            .then(self.tri.cmp(&o.tri))
    }
}

/// A node's events, one sorted list per axis.
type Lists = [Vec<Event>; 3];

/// True for a triangle the tree holds: finite box that is not a point (the scene collapses
/// degenerate triangles to a point; they are never hit).
pub(super) fn in_tree(b: &Aabb) -> bool {
    b.min.is_finite() && b.max.is_finite() && b.min != b.max
}

/// Where a split sends a triangle.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    Below,
    Above,
    Both,
}

/// The chosen plane.
#[derive(Clone, Copy, Debug)]
struct Split {
    axis: usize,
    pos: f32,
    cost: f32,
    /// Triangles lying in the plane go below (else above).
    planar_below: bool,
}

/// Nodes and ids of a subtree, indices relative to its own start.
#[derive(Default)]
struct Subtree {
    nodes: Vec<Node>,
    ids: Vec<u32>,
    depth: usize,
}

impl Subtree {
    /// Appends `s` (built on its own), shifting its indices.
    fn append(&mut self, s: Subtree) {
        let (dn, di) = (self.nodes.len() as u32, self.ids.len() as u32);
        self.nodes.extend(s.nodes.into_iter().map(|n| n.shifted(dn, di)));
        self.ids.extend(s.ids);
        self.depth = self.depth.max(s.depth);
    }
}

/// Builds the tree (configuration already checked).
pub(super) fn build(soup: &TriangleSoup, cfg: &BuildConfig) -> Result<KdTree> {
    let n = soup.len();
    if n > MAX_INDEX {
        return Err(Error::Invalid(format!(
            "kd-tree build: {n} triangles, at most {MAX_INDEX} supported"
        )));
    }
    let boxes: Vec<Aabb> = (0..n).into_par_iter().map(|i| soup.bounds(i)).collect();
    let held: Vec<u32> = (0..n as u32)
        .filter(|&i| in_tree(&boxes[i as usize]))
        .collect();
    let bounds = held
        .par_iter()
        .map(|&i| boxes[i as usize])
        .reduce(|| Aabb::EMPTY, Aabb::union);
    let lists: Lists = [0, 1, 2].map(|a| {
        let mut ev = Vec::with_capacity(2 * held.len());
        for &i in &held {
            let b = &boxes[i as usize];
            if b.min[a] == b.max[a] {
                ev.push(Event::new(b.min[a], i, PLANAR));
            } else {
                ev.push(Event::new(b.min[a], i, START));
                ev.push(Event::new(b.max[a], i, END));
            }
        }
        ev.par_sort_unstable_by(Event::cmp);
        ev
    });
    let ctx = Ctx {
        cfg,
        boxes: &boxes,
        limit: cfg.depth_limit(held.len()),
    };
    let tree = ctx.subtree(lists, held.len(), bounds, 0);
    if tree.nodes.len() > MAX_INDEX || tree.ids.len() > u32::MAX as usize {
        return Err(Error::Invalid(format!(
            "kd-tree build: {} nodes and {} references exceed the 2^30-node layout",
            tree.nodes.len(),
            tree.ids.len()
        )));
    }
    let (mut nodes, mut ids) = (tree.nodes, tree.ids);
    nodes.shrink_to_fit();
    ids.shrink_to_fit();
    Ok(KdTree {
        nodes,
        ids,
        bounds,
        depth: tree.depth,
        triangles: n,
    })
}

/// What every node of one build shares.
struct Ctx<'a> {
    cfg: &'a BuildConfig,
    boxes: &'a [Aabb],
    limit: usize,
}

impl Ctx<'_> {
    /// The subtree of a node holding `n` triangles with events `lists` in `cell` at `depth`.
    fn subtree(&self, lists: Lists, n: usize, cell: Aabb, depth: usize) -> Subtree {
        let mut out = Subtree::default();
        self.node(&mut out, lists, n, cell, depth);
        out
    }

    /// Appends the subtree of a node to `out`.
    fn node(&self, out: &mut Subtree, lists: Lists, n: usize, cell: Aabb, depth: usize) {
        out.depth = out.depth.max(depth);
        let split = if n <= self.cfg.max_leaf || depth >= self.limit {
            None
        } else {
            (0..3)
                .filter_map(|a| self.sweep(&lists[a], n, &cell, a))
                .reduce(|x, y| if y.cost < x.cost { y } else { x })
                .filter(|s| s.cost < self.cfg.intersection_cost * n as f32)
        };
        let Some(split) = split else {
            let mut ids: Vec<u32> = lists[0]
                .iter()
                .filter(|e| e.kind != END)
                .map(|e| e.tri)
                .collect();
            ids.sort_unstable();
            out.nodes.push(Node::leaf(out.ids.len() as u32, ids.len() as u32));
            out.ids.extend(ids);
            return;
        };
        let (a, s) = (split.axis, split.pos);
        let (below, nb, above, na) = self.divide(lists, &cell, split);
        let (mut bcell, mut acell) = (cell, cell);
        bcell.max[a] = s;
        acell.min[a] = s;
        let me = out.nodes.len();
        out.nodes.push(Node::interior(a, s, 0));
        if n >= self.cfg.parallel_threshold {
            let (b, t) = rayon::join(
                || self.subtree(below, nb, bcell, depth + 1),
                || self.subtree(above, na, acell, depth + 1),
            );
            out.append(b);
            out.nodes[me] = Node::interior(a, s, out.nodes.len() as u32);
            out.append(t);
        } else {
            self.node(out, below, nb, bcell, depth + 1);
            out.nodes[me] = Node::interior(a, s, out.nodes.len() as u32);
            self.node(out, above, na, acell, depth + 1);
        }
    }

    /// The cheapest plane on axis `a` strictly inside `cell`, by sweeping its sorted events.
    fn sweep(&self, ev: &[Event], n: usize, cell: &Aabb, a: usize) -> Option<Split> {
        let area = cell.surface_area();
        if !(area > 0.0) {
            return None;
        }
        let c = self.cfg;
        let sah = |pb: f32, pa: f32, nb: usize, na: usize| {
            let bonus = if nb == 0 || na == 0 { 1.0 - c.empty_bonus } else { 1.0 };
            c.traversal_cost + c.intersection_cost * bonus * (pb * nb as f32 + pa * na as f32)
        };
        let (mut nb, mut na) = (0usize, n);
        let mut best: Option<Split> = None;
        let mut i = 0;
        while i < ev.len() {
            let p = ev[i].pos;
            let mut count = [0usize; 3];
            for kind in [END, PLANAR, START] {
                while i < ev.len() && ev[i].pos == p && ev[i].kind == kind {
                    count[kind as usize] += 1;
                    i += 1;
                }
            }
            let [ends, planar, starts] = count;
            na -= ends + planar;
            if cell.min[a] < p && p < cell.max[a] {
                let (mut b, mut t) = (*cell, *cell);
                b.max[a] = p;
                t.min[a] = p;
                let (pb, pa) = (b.surface_area() / area, t.surface_area() / area);
                let below = sah(pb, pa, nb + planar, na);
                let above = sah(pb, pa, nb, na + planar);
                let (cost, planar_below) = if below <= above {
                    (below, true)
                } else {
                    (above, false)
                };
                if best.is_none_or(|b| cost < b.cost) {
                    best = Some(Split {
                        axis: a,
                        pos: p,
                        cost,
                        planar_below,
                    });
                }
            }
            nb += starts + planar;
        }
        best
    }

    /// Where `split` sends the triangle of box `b` in `cell`: by its box clipped to the cell
    /// (the same as by its whole box on the split axis, the plane being strictly inside).
    fn side(&self, tri: u32, cell: &Aabb, split: Split) -> Side {
        let (a, s) = (split.axis, split.pos);
        let b = &self.boxes[tri as usize];
        let (lo, hi) = (b.min[a].max(cell.min[a]), b.max[a].min(cell.max[a]));
        if lo == s && hi == s {
            if split.planar_below {
                Side::Below
            } else {
                Side::Above
            }
        } else if hi <= s {
            Side::Below
        } else if lo >= s {
            Side::Above
        } else {
            Side::Both
        }
    }

    /// The children's event lists and triangle counts: each list filtered in order; on the split
    /// axis a straddling triangle's box is clipped to the plane (a new end below, a new start
    /// above), and those new events are sorted and merged in (the only sorting after the first).
    fn divide(&self, lists: Lists, cell: &Aabb, split: Split) -> (Lists, usize, Lists, usize) {
        let a = split.axis;
        let mut below: Lists = Default::default();
        let mut above: Lists = Default::default();
        let (mut nb, mut na) = (0, 0);
        for (axis, ev) in lists.into_iter().enumerate() {
            let (b, t) = (&mut below[axis], &mut above[axis]);
            let (mut new_b, mut new_t) = (Vec::new(), Vec::new());
            for e in ev {
                let side = self.side(e.tri, cell, split);
                if axis == 0 && e.kind != END {
                    nb += (side != Side::Above) as usize;
                    na += (side != Side::Below) as usize;
                }
                match side {
                    Side::Below => b.push(e),
                    Side::Above => t.push(e),
                    Side::Both if axis != a => {
                        b.push(e);
                        t.push(e);
                    }
                    Side::Both if e.kind == START => {
                        b.push(e);
                        new_t.push(Event::new(split.pos, e.tri, START));
                    }
                    Side::Both => {
                        t.push(e);
                        new_b.push(Event::new(split.pos, e.tri, END));
                    }
                }
            }
            if axis == a {
                *b = merge(std::mem::take(b), new_b);
                *t = merge(std::mem::take(t), new_t);
            }
        }
        (below, nb, above, na)
    }
}

/// Merges the sorted list `x` with the events `y` (sorted here).
fn merge(x: Vec<Event>, mut y: Vec<Event>) -> Vec<Event> {
    if y.is_empty() {
        return x;
    }
    y.sort_unstable_by(Event::cmp);
    let mut out = Vec::with_capacity(x.len() + y.len());
    let (mut i, mut j) = (0, 0);
    while i < x.len() && j < y.len() {
        if x[i].cmp(&y[j]) != Ordering::Greater {
            out.push(x[i]);
            i += 1;
        } else {
            out.push(y[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&x[i..]);
    out.extend_from_slice(&y[j..]);
    out
}
