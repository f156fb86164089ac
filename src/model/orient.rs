//! Orienting estimated normals after Hoppe et al. 1992: signs propagated
//! along a minimum spanning tree of the k-NN graph, each component without
//! a trusted normal seeded at an extreme point.

use super::pointwise::PROGRESS_STEP;
use super::stage::Stage;
use glam::Vec3;

/// Hoppe et al. 1992 orientation: flips normals so that they agree along a
/// minimum spanning tree of the k-NN graph (weights `1 - |n_i . n_j|`).
pub(super) fn orient(
    pts: &[[f32; 3]],
    normals: &mut [Vec3],
    estimated: &[bool],
    graph: &[u32],
    kg: usize,
    bar: &Stage,
) {
    let n = pts.len();
    // Reverse edges, so that the graph is symmetric: j may be i's neighbour
    // without i being j's.
    let mut rev_start = vec![0usize; n + 1];
    for &j in graph {
        rev_start[j as usize + 1] += 1;
    }
    for i in 0..n {
        rev_start[i + 1] += rev_start[i];
    }
    let mut fill = rev_start.clone();
    let mut rev = vec![0u32; graph.len()];
    for (e, &j) in graph.iter().enumerate() {
        let slot = &mut fill[j as usize];
        rev[*slot] = (e / kg) as u32;
        *slot += 1;
    }
    drop(fill);
    let neighbours = |i: usize| {
        graph[i * kg..(i + 1) * kg]
            .iter()
            .chain(&rev[rev_start[i]..rev_start[i + 1]])
            .map(|&j| j as usize)
    };

    const UNSEEN: u8 = 0;
    const QUEUED: u8 = 1;
    const DONE: u8 = 2;
    let mut state: Vec<u8> = estimated
        .iter()
        .map(|&e| if e { UNSEEN } else { DONE })
        .collect();
    let mut queue = BucketQueue::new();
    let push_edges = |i: usize, state: &[u8], normals: &[Vec3], queue: &mut BucketQueue| {
        for j in neighbours(i) {
            if state[j] != DONE {
                queue.push(normals[i].dot(normals[j]), j as u32, i as u32);
            }
        }
    };
    let mut done = 0usize;
    let mut grow = |queue: &mut BucketQueue, state: &mut [u8], normals: &mut [Vec3]| {
        while let Some((to, from)) = queue.pop() {
            let (to, from) = (to as usize, from as usize);
            if state[to] == DONE {
                continue;
            }
            if normals[to].dot(normals[from]) < 0.0 {
                normals[to] = -normals[to];
            }
            state[to] = DONE;
            push_edges(to, state, normals, queue);
            done += 1;
            if done.is_multiple_of(PROGRESS_STEP) {
                bar.advance(PROGRESS_STEP as u64);
            }
        }
    };

    // Trusted normals first: they orient everything connected to them.
    for i in 0..n {
        if state[i] == DONE {
            push_edges(i, &state, normals, &mut queue);
        }
    }
    grow(&mut queue, &mut state, normals);

    // What remains are components without a trusted normal: seed each.
    let mut members: Vec<usize> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    for start in 0..n {
        if state[start] != UNSEEN {
            continue;
        }
        members.clear();
        stack.push(start);
        state[start] = QUEUED;
        while let Some(i) = stack.pop() {
            members.push(i);
            for j in neighbours(i) {
                if state[j] == UNSEEN {
                    state[j] = QUEUED;
                    stack.push(j);
                }
            }
        }
        let seed = choose_seed(pts, normals, &members);
        state[seed] = DONE;
        push_edges(seed, &state, normals, &mut queue);
        grow(&mut queue, &mut state, normals);
    }
    bar.finish();
}

/// Buckets for the edge weights of the orientation tree. Prim's algorithm
/// only needs the cheapest edge next, and an exact order among nearly equal
/// weights does not matter, so weights are quantised: the bucket is linear in
/// `sqrt(1 - |cos|)`, about the angle between the normals (0.35 degree per
/// bucket near parallel). Pushes are O(1) and pops scan up from the lowest
/// non-empty bucket; on smooth surfaces nearly every edge lands in the first
/// few buckets. Several times faster than a binary heap here.
struct BucketQueue {
    buckets: Vec<Vec<(u32, u32)>>,
    lowest: usize,
    len: usize,
}

impl BucketQueue {
    const BUCKETS: usize = 256;

    fn new() -> Self {
        Self {
            buckets: vec![Vec::new(); Self::BUCKETS],
            lowest: Self::BUCKETS,
            len: 0,
        }
    }

    /// Queues the edge `from -> to` whose normals have cosine `cos`.
    #[inline]
    fn push(&mut self, cos: f32, to: u32, from: u32) {
        let w = (1.0 - cos.abs()).max(0.0).sqrt();
        // NaN and values >= 1 both land in the last bucket.
        let b = ((w * Self::BUCKETS as f32) as usize).min(Self::BUCKETS - 1);
        self.buckets[b].push((to, from));
        self.lowest = self.lowest.min(b);
        self.len += 1;
    }

    /// The queued edge of (about) the lowest weight, as `(to, from)`.
    #[inline]
    fn pop(&mut self) -> Option<(u32, u32)> {
        if self.len == 0 {
            self.lowest = Self::BUCKETS;
            return None;
        }
        while self.buckets[self.lowest].is_empty() {
            self.lowest += 1;
        }
        self.len -= 1;
        self.buckets[self.lowest].pop()
    }
}

/// Among the six extreme points of a component, the one whose normal is most
/// aligned with its axis; that normal is flipped to point outward along it.
fn choose_seed(pts: &[[f32; 3]], normals: &mut [Vec3], members: &[usize]) -> usize {
    let mut best = (members[0], 0usize, false, -1.0f32); // point, axis, negative side, score
    for axis in 0..3 {
        for negative in [false, true] {
            let key = |i: &usize| {
                let v = pts[*i][axis];
                if negative { -v } else { v }
            };
            let Some(&i) = members.iter().max_by(|a, b| key(a).total_cmp(&key(b))) else {
                continue;
            };
            let score = normals[i][axis].abs();
            if score > best.3 {
                best = (i, axis, negative, score);
            }
        }
    }
    let (i, axis, negative, _) = best;
    let outward = if negative { -1.0 } else { 1.0 };
    if normals[i][axis] * outward < 0.0 {
        normals[i] = -normals[i];
    }
    i
}
