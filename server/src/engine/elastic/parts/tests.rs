//! Parts cover every vertex once, and every element falls in the part that holds all
//! its vertices, or among the crossing ones.

use super::*;
use crate::engine::mesh::reverse_cuthill_mckee;
use crate::engine::testing::liver_mesh;

#[test]
fn ranges_cover_the_vertices_in_equal_shares() {
    for (n, count) in [(181, 1), (181, 2), (181, 7), (10, 10), (5, 9), (1, 3)] {
        let parts = Parts::new(n, count, std::iter::empty());
        assert_eq!(parts.count(), count.min(n));
        let mut next = 0;
        for t in 0..parts.count() {
            let r = parts.range(t);
            assert_eq!(r.start, next, "{n} in {count}: parts are contiguous");
            assert!(
                r.len().abs_diff(n / parts.count()) <= 1,
                "{n} in {count}: {r:?}"
            );
            for v in r.clone() {
                assert_eq!(parts.of(v), t);
            }
            next = r.end;
        }
        assert_eq!(next, n);
    }
    // A count of 0 is one part.
    assert_eq!(Parts::new(4, 0, std::iter::empty()).count(), 1);
}

#[test]
fn every_element_is_in_its_vertices_part_or_crossing() {
    let file = liver_mesh();
    let mesh = file.renumbered(&reverse_cuthill_mckee(file.vertex_count(), &file.edges));
    for count in [1, 2, 3, 8] {
        let parts = Parts::new(mesh.vertex_count(), count, mesh.tets.iter().copied());
        let mut seen = vec![0u32; mesh.tets.len()];
        for t in 0..count {
            let group = parts.elements(t);
            assert!(group.windows(2).all(|w| w[0] < w[1]), "ascending");
            for &e in group {
                seen[e as usize] += 1;
                assert!(
                    mesh.tets[e as usize]
                        .iter()
                        .all(|&v| parts.of(v as usize) == t)
                );
            }
        }
        for &e in parts.crossing() {
            seen[e as usize] += 1;
            let tet = mesh.tets[e as usize];
            assert!(
                tet.iter()
                    .any(|&v| parts.of(v as usize) != parts.of(tet[0] as usize))
            );
        }
        assert!(
            seen.iter().all(|&s| s == 1),
            "{count} parts: each element once"
        );
        if count == 1 {
            assert!(parts.crossing().is_empty());
        }
    }
}

/// The integrator hands its parts to the CG workspace and the corotational update:
/// a clone reads the same element lists, not a copy of them.
#[test]
fn a_clone_shares_the_element_lists() {
    let mesh = liver_mesh();
    let parts = Parts::new(mesh.vertex_count(), 2, mesh.tets.iter().copied());
    let copy = parts.clone();
    for t in 0..=parts.count() {
        let (a, b) = if t < parts.count() {
            (parts.elements(t), copy.elements(t))
        } else {
            (parts.crossing(), copy.crossing())
        };
        assert_eq!(a, b);
        assert!(std::ptr::eq(a, b), "group {t} was copied");
    }
}
