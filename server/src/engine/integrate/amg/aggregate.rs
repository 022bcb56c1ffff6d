//! Strength of connection and greedy aggregation (Vaněk, Mandel and Brezina 1996,
//! "Algebraic multigrid by smoothed aggregation for second and fourth order elliptic
//! problems", §3).
//!
//! A level's unknowns come in nodes (a vertex's three displacements on the fine
//! level, an aggregate's up to six rigid-body coefficients on coarser ones), and
//! strength is measured between nodes, on the Frobenius norms of the blocks:
//! nodes `i ≠ j` are strongly connected when
//!
//! `‖A_ij‖ ≥ θ √(‖A_ii‖ ‖A_jj‖)`.
//!
//! Aggregation then groups nodes in three passes: (1) every node whose strong
//! neighbours are all still free starts an aggregate with them (a "root" and its
//! neighbourhood: aggregates of about the size of a vertex's star, so that the coarse
//! level has a few times fewer unknowns); (2) each node left over joins the aggregate
//! of the pass-1 neighbour it is most strongly connected to; (3) whatever remains
//! forms aggregates with its still-free strong neighbours. Nodes without any strong
//! neighbour (their row is dominated by its diagonal block: the smoother alone
//! resolves them) and excluded nodes (supports) belong to no aggregate: their rows of
//! the prolongator are zero.

use super::sparse::Csr;

/// Marks a node that belongs to no aggregate.
pub const NONE: u32 = u32::MAX;

/// The strongly connected neighbours of each node, with the strength
/// `‖A_ij‖ / √(‖A_ii‖ ‖A_jj‖)` of each connection.
pub struct Strength {
    pub start: Vec<usize>,
    pub node: Vec<u32>,
    pub strength: Vec<f64>,
}

/// The strong connections of `a`, whose node `k` holds the unknowns
/// `node_start[k]..node_start[k + 1]`, at threshold `theta`; excluded nodes have none.
pub fn strength(a: &Csr, node_start: &[usize], excluded: &[bool], theta: f64) -> Strength {
    let nodes = node_start.len() - 1;
    let mut node_of = vec![0u32; a.rows];
    for k in 0..nodes {
        node_of[node_start[k]..node_start[k + 1]].fill(k as u32);
    }
    let mut acc = vec![0.0f64; nodes];
    let mut seen = vec![usize::MAX; nodes];
    let mut touched: Vec<u32> = Vec::new();
    // Block norms ‖A_kj‖ of every node row, then the diagonal ones.
    let mut rows: Vec<Vec<(u32, f64)>> = Vec::with_capacity(nodes);
    let mut diag = vec![0.0f64; nodes];
    for k in 0..nodes {
        touched.clear();
        for r in node_start[k]..node_start[k + 1] {
            let (cs, vs) = a.row(r);
            for (&c, &v) in cs.iter().zip(vs) {
                let j = node_of[c as usize] as usize;
                if seen[j] != k {
                    seen[j] = k;
                    acc[j] = 0.0;
                    touched.push(j as u32);
                }
                acc[j] += v * v;
            }
        }
        let mut row = Vec::with_capacity(touched.len());
        for &j in &touched {
            let norm = acc[j as usize].sqrt();
            if j as usize == k {
                diag[k] = norm;
            } else {
                row.push((j, norm));
            }
        }
        rows.push(row);
    }
    let mut start = vec![0];
    let (mut node, mut strength) = (Vec::new(), Vec::new());
    for k in 0..nodes {
        if !excluded[k] {
            for &(j, norm) in &rows[k] {
                let scale = (diag[k] * diag[j as usize]).sqrt();
                if !excluded[j as usize] && scale > 0.0 && norm >= theta * scale {
                    node.push(j);
                    strength.push(norm / scale);
                }
            }
        }
        start.push(node.len());
    }
    Strength {
        start,
        node,
        strength,
    }
}

/// The aggregate of each node ([`NONE`] for none) and the number of aggregates.
pub fn aggregate(s: &Strength, excluded: &[bool]) -> (Vec<u32>, usize) {
    let nodes = s.start.len() - 1;
    let neighbours = |k: usize| &s.node[s.start[k]..s.start[k + 1]];
    let mut agg = vec![NONE; nodes];
    let mut count = 0u32;
    // Pass 1: roots whose whole strong neighbourhood is free.
    for k in 0..nodes {
        let n = neighbours(k);
        if excluded[k] || agg[k] != NONE || n.is_empty() {
            continue;
        }
        if n.iter().all(|&j| agg[j as usize] == NONE) {
            agg[k] = count;
            for &j in n {
                agg[j as usize] = count;
            }
            count += 1;
        }
    }
    // Pass 2: join the most strongly connected pass-1 aggregate.
    let first = agg.clone();
    for k in 0..nodes {
        if excluded[k] || agg[k] != NONE {
            continue;
        }
        let range = s.start[k]..s.start[k + 1];
        let best = s.node[range.clone()]
            .iter()
            .zip(&s.strength[range])
            .filter(|(j, _)| first[**j as usize] != NONE)
            .max_by(|a, b| a.1.total_cmp(b.1));
        if let Some((&j, _)) = best {
            agg[k] = first[j as usize];
        }
    }
    // Pass 3: what remains, with its free strong neighbours.
    for k in 0..nodes {
        let n = neighbours(k);
        if excluded[k] || agg[k] != NONE || n.is_empty() {
            continue;
        }
        agg[k] = count;
        for &j in n {
            if agg[j as usize] == NONE {
                agg[j as usize] = count;
            }
        }
        count += 1;
    }
    (agg, count as usize)
}
