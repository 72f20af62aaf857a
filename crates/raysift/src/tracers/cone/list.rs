//! The answer of one cone while it is built: the up-to-`n` nearest eligible triangles sorted by
//! `(t, id)` (Eq. 1's `I`, insertion-sorted as the paper does), and the bound a walker culls with.

/// The `n` nearest so far (`n = None`: all, sorted once at the end).
#[derive(Clone, Debug)]
pub struct Nearest {
    n: Option<usize>,
    t_near: f32,
    near_id: u32,
    t_far: f32,
    /// `(t, id)`, sorted when `n` is bounded.
    items: Vec<(f32, u32)>,
}

impl Nearest {
    /// An empty list keeping `n` (reset before each cone).
    pub fn new(n: Option<usize>) -> Self {
        Self {
            n,
            t_near: 0.0,
            near_id: 0,
            t_far: f32::INFINITY,
            items: Vec::with_capacity(n.unwrap_or(0).min(4096)),
        }
    }

    /// Empties the list for a cone with these bounds.
    pub fn reset(&mut self, t_near: f32, near_id: u32, t_far: f32) {
        self.items.clear();
        (self.t_near, self.near_id, self.t_far) = (t_near, near_id, t_far);
    }

    /// True when `(t, id)` is in the cone's range: `t ≤ t_far`, `(t, id) ≥ (t_near, near_id)`.
    #[inline(always)]
    pub fn eligible(&self, t: f32, id: u32) -> bool {
        t <= self.t_far && (t > self.t_near || (t == self.t_near && id >= self.near_id))
    }

    /// Nodes whose range ends before this cannot hold an eligible triangle.
    #[inline(always)]
    pub fn t_near(&self) -> f32 {
        self.t_near
    }

    /// Nodes whose range starts beyond this cannot improve the answer: `t_n` when the list is
    /// full, else `t_far`. (Inclusive: a triangle at exactly `t_n` with a smaller id still
    /// enters, so a node starting at `t_n` is visited.)
    #[inline(always)]
    pub fn bound(&self) -> f32 {
        match self.n {
            Some(n) if self.items.len() == n => {
                self.items.last().map_or(f32::NEG_INFINITY, |x| x.0)
            }
            _ => self.t_far,
        }
    }

    /// Offers triangle `id` at `t`: kept when eligible and among the `n` nearest; a second offer
    /// of the same triangle (a structure holding it in several leaves) is ignored.
    #[inline]
    pub fn offer(&mut self, t: f32, id: u32) {
        if !self.eligible(t, id) {
            return;
        }
        let Some(n) = self.n else {
            self.items.push((t, id));
            return;
        };
        if n == 0 {
            return;
        }
        let key = (t, id);
        let full = self.items.len() == n;
        if full && !lt(key, *self.items.last().expect("full, n > 0")) {
            return;
        }
        // Insertion sort from the back (the paper's "insertion sorting").
        let mut pos = self.items.len();
        while pos > 0 && lt(key, self.items[pos - 1]) {
            pos -= 1;
        }
        if pos > 0 && self.items[pos - 1] == key {
            return; // already there
        }
        if full {
            self.items.pop();
        }
        self.items.insert(pos, key);
    }

    /// Moves the sorted answer out (appending ids and `t`s), leaving the list empty.
    pub fn drain_into(&mut self, prim: &mut Vec<u32>, t: &mut Vec<f32>) {
        if self.n.is_none() {
            self.items
                .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            self.items.dedup();
        }
        for &(tt, id) in &self.items {
            prim.push(id);
            t.push(tt);
        }
        self.items.clear();
    }

    /// Entries held now.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

/// `(t, id)` order (t is never NaN here).
#[inline(always)]
fn lt(a: (f32, u32), b: (f32, u32)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 < b.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(l: &mut Nearest) -> Vec<(u32, f32)> {
        let (mut p, mut t) = (vec![], vec![]);
        l.drain_into(&mut p, &mut t);
        p.into_iter().zip(t).collect()
    }

    #[test]
    fn keeps_the_n_nearest_sorted_with_ties_by_id_and_no_duplicates() {
        let offers = [
            (3.0, 7),
            (1.0, 9),
            (1.0, 2),
            (5.0, 1),
            (1.0, 2),
            (2.0, 4),
            (0.5, 8),
        ];
        let mut l = Nearest::new(Some(3));
        let mut all = Nearest::new(None);
        for (t, id) in offers {
            l.offer(t, id);
            all.offer(t, id);
        }
        assert_eq!(drain(&mut l), vec![(8, 0.5), (2, 1.0), (9, 1.0)]);
        assert_eq!(
            drain(&mut all),
            vec![(8, 0.5), (2, 1.0), (9, 1.0), (4, 2.0), (7, 3.0), (1, 5.0)]
        );
        // Continuing after (1.0, 9): t_near = 1.0, near_id = 10.
        l.reset(1.0, 10, f32::INFINITY);
        for (t, id) in offers {
            l.offer(t, id);
        }
        assert_eq!(drain(&mut l), vec![(4, 2.0), (7, 3.0), (1, 5.0)]);
        // t_far is inclusive; bound is t_far until full, then t_n.
        l.reset(0.0, 0, 3.0);
        assert_eq!(l.bound(), 3.0);
        for (t, id) in offers {
            l.offer(t, id);
        }
        assert_eq!(l.bound(), 1.0);
        l.reset(0.0, 0, 3.0);
        l.offer(3.0, 1);
        l.offer(3.0000002, 0);
        assert_eq!(drain(&mut l), vec![(1, 3.0)]);
    }
}
