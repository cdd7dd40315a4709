//! The solution's links, grouped by receiver: 16 bytes a link for what the sweeps read,
//! 6 more for what only the refinement rounds read while any may still run.
//!
//! The links are sorted by (receiver, source). Each receiver is stored once, with where its
//! run of links starts (compressed sparse rows), so a link keeps only its source and its
//! [`PackedTransfer`]. The misses near the receivers' corners (`Link::miss`), which only the
//! oracle's joint check of a receiver's links reads, are a separate array, dropped once the
//! link budget has stopped refinement for good (no round runs again; on Sponza that is
//! 112 MB of 18.7 M links). The refinement rounds take the links out as [`Link`]s (each
//! with its receiver and misses, NaN where dropped) and put them back here when they end.

use super::NodeId;
use super::link::{BF16_NAN, Link, PackedTransfer};
use rayon::prelude::*;
use std::borrow::Borrow;
use std::ops::Range;

/// A link as the solution stores it under its receiver: 16 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct StoredLink {
    pub source: NodeId,
    pub transfer: PackedTransfer,
}

impl StoredLink {
    /// The link to `receiver` with misses `miss` (bfloat16; see [`Link::miss`]).
    pub fn to(&self, receiver: NodeId, miss: [u16; 3]) -> Link {
        Link {
            receiver,
            source: self.source,
            transfer: self.transfer,
            miss,
        }
    }
}

/// The links, grouped by receiver (see the module documentation).
#[derive(Default)]
pub(super) struct LinkTable {
    /// The receivers, ascending, each once.
    receivers: Vec<NodeId>,
    /// Receiver k's links are `links[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    links: Vec<StoredLink>,
    /// Per link, [`Link::miss`]; empty once no refinement round can run again.
    misses: Vec<[u16; 3]>,
}

/// Most links a table holds: its offsets are u32 (`solver::types::MAX_LINK_BUDGET` keeps
/// the links well below).
const MAX_LINKS: usize = u32::MAX as usize;

impl LinkTable {
    /// The table of `links` (links or references to them), which are sorted by
    /// (receiver, source), the order every sum runs in; the misses are kept when
    /// `keep_misses`. Past [`MAX_LINKS`] the links left over are dropped.
    pub fn new<L: Borrow<Link> + Sync>(links: &[L], keep_misses: bool) -> LinkTable {
        let links = &links[..links.len().min(MAX_LINKS)];
        let at = |i: usize| -> &Link { links[i].borrow() };
        debug_assert!(
            (1..links.len())
                .all(|i| (at(i - 1).receiver, at(i - 1).source) <= (at(i).receiver, at(i).source))
        );
        let stored = links
            .par_iter()
            .map(|l| {
                let l = l.borrow();
                StoredLink {
                    source: l.source,
                    transfer: l.transfer,
                }
            })
            .collect();
        let misses = if keep_misses {
            links.par_iter().map(|l| l.borrow().miss).collect()
        } else {
            Vec::new()
        };
        let mut start: Vec<u32> = (0..links.len())
            .into_par_iter()
            .with_min_len(1 << 14)
            .filter(|&i| i == 0 || at(i - 1).receiver != at(i).receiver)
            .map(|i| i as u32)
            .collect();
        let receivers = start.par_iter().map(|&i| at(i as usize).receiver).collect();
        start.push(links.len() as u32);
        LinkTable {
            receivers,
            start,
            links: stored,
            misses,
        }
    }

    /// The links with their receivers and misses (NaN where dropped), in the table's
    /// order; the table is left empty.
    pub fn take(&mut self) -> Vec<Link> {
        const CHUNK: usize = 1 << 16;
        let table = std::mem::take(self);
        let blank = StoredLink {
            source: NodeId(0),
            transfer: PackedTransfer::default(),
        };
        let mut out = vec![blank.to(NodeId(0), [0; 3]); table.links.len()];
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                let first = c * CHUNK;
                // The receiver whose run holds the chunk's first link.
                let mut k = table.start.partition_point(|&s| s as usize <= first) - 1;
                for (i, slot) in (first..).zip(chunk) {
                    while table.start[k + 1] as usize <= i {
                        k += 1;
                    }
                    let miss = table.misses.get(i).copied().unwrap_or([BF16_NAN; 3]);
                    *slot = table.links[i].to(table.receivers[k], miss);
                }
            });
        out
    }

    pub fn len(&self) -> usize {
        self.links.len()
    }

    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// Bytes the table takes.
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.receivers.len() * size_of::<NodeId>()
            + self.start.len() * size_of::<u32>()
            + self.links.len() * size_of::<StoredLink>()
            + self.misses.len() * size_of::<[u16; 3]>()
    }

    /// Link `i` (in the table's order).
    pub fn link(&self, i: usize) -> &StoredLink {
        &self.links[i]
    }

    /// The links' positions of receiver number `k`.
    fn run(&self, k: usize) -> Range<usize> {
        self.start[k] as usize..self.start[k + 1] as usize
    }

    /// Each receiver with its links, in order, in parallel.
    pub fn par_groups(&self) -> impl IndexedParallelIterator<Item = (NodeId, &[StoredLink])> {
        (0..self.receivers.len())
            .into_par_iter()
            .map(|k| (self.receivers[k], &self.links[self.run(k)]))
    }

    /// Each receiver with its links, in order.
    pub fn groups(&self) -> impl Iterator<Item = (NodeId, &[StoredLink])> {
        (0..self.receivers.len()).map(|k| (self.receivers[k], &self.links[self.run(k)]))
    }

    /// Every link with its receiver, in order.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, &StoredLink)> {
        self.groups()
            .flat_map(|(r, links)| links.iter().map(move |l| (r, l)))
    }

    /// The links to receiver `id`.
    pub fn to(&self, id: NodeId) -> &[StoredLink] {
        match self.receivers.binary_search(&id) {
            Ok(k) => &self.links[self.run(k)],
            Err(_) => &[],
        }
    }

    /// Ascending link positions `sorted` cut into runs of one receiver each, with that
    /// receiver. The receivers are found by galloping forward from the last one (what an
    /// edit reaches is often close together), each run's end by a scan.
    pub fn split_by_receiver<'a>(&self, sorted: &'a [u32]) -> Vec<(NodeId, &'a [u32])> {
        let mut runs = Vec::new();
        let mut rest = sorted;
        // The run that holds the next position starts at or after `k`.
        let mut k = 0;
        while let Some(&first) = rest.first() {
            // start[lo] <= first < start[hi]; start's last entry is the number of links,
            // above every position.
            let (mut lo, mut step) = (k, 1);
            let mut hi = lo + 1;
            while self.start[hi] <= first {
                lo = hi;
                step *= 2;
                hi = (lo + step).min(self.start.len() - 1);
            }
            k = lo + self.start[lo..hi].partition_point(|&s| s <= first) - 1;
            let end = self.start[k + 1];
            let n = rest.iter().take_while(|&&i| i < end).count();
            runs.push((self.receivers[k], &rest[..n]));
            rest = &rest[n..];
        }
        runs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sampling::{hash, unit};
    use crate::solver::hierarchical::transfer::Transfer;

    #[test]
    fn a_stored_link_is_16_bytes() {
        assert_eq!(std::mem::size_of::<StoredLink>(), 16);
    }

    /// Random links sorted as the solution keeps them: the table gives them back as they
    /// were (with NaN misses where it dropped them), finds each receiver's run by lookup
    /// and by cutting positions, and counts its bytes.
    #[test]
    fn the_table_gives_back_the_links_it_was_given() {
        let mut links: Vec<Link> = (0..5_000u64)
            .map(|k| {
                let h = hash(k);
                let id = |x: u64| {
                    let n = (hash(h ^ x) % 300) as u32;
                    if n.is_multiple_of(5) {
                        NodeId::of_cluster(n)
                    } else {
                        NodeId::surface(n)
                    }
                };
                let t = Transfer {
                    values: [unit(hash(h ^ 3)), unit(hash(h ^ 4)), 0.5],
                    spread: unit(hash(h ^ 5)),
                    partial: k.is_multiple_of(2),
                    rays: 0,
                    toward: [0.2, 0.3],
                    miss: [unit(hash(h ^ 6)), -1.0, 0.25],
                };
                Link::new(id(1), id(2), &t)
            })
            .collect();
        links.sort_by_key(|l| (l.receiver, l.source));
        for keep in [true, false] {
            let mut table = LinkTable::new(&links, keep);
            assert_eq!(table.len(), links.len());
            let receivers = table.receivers.len();
            assert_eq!(
                table.bytes(),
                links.len() * if keep { 22 } else { 16 } + receivers * 8 + 4
            );
            for (i, (r, l)) in table.iter().enumerate() {
                assert_eq!(
                    (r, l.source, l.transfer),
                    (links[i].receiver, links[i].source, links[i].transfer)
                );
            }
            for (r, group) in table.groups() {
                assert_eq!(table.to(r), group);
            }
            assert!(table.to(NodeId::surface(100_000)).is_empty());
            // Dense, sparse (long gallops) and every position.
            let patterns: [fn(u32) -> bool; 3] = [|i| i % 7 < 3, |i| i % 997 == 5, |_| true];
            for every in patterns {
                let positions: Vec<u32> = (0..links.len() as u32).filter(|&i| every(i)).collect();
                let runs = table.split_by_receiver(&positions);
                for (r, run) in &runs {
                    assert!(!run.is_empty());
                    assert!(run.iter().all(|&i| links[i as usize].receiver == *r));
                }
                assert!(runs.windows(2).all(|w| w[0].0 < w[1].0));
                let cut: usize = runs.iter().map(|r| r.1.len()).sum();
                assert_eq!(cut, positions.len());
            }
            let back = table.take();
            assert!(table.is_empty());
            for (got, want) in back.iter().zip(&links) {
                assert_eq!(
                    (got.receiver, got.source, got.transfer),
                    (want.receiver, want.source, want.transfer)
                );
                if keep {
                    assert_eq!(got.miss, want.miss);
                } else {
                    assert!(got.miss().iter().all(|m| m.is_nan()));
                }
            }
            assert_eq!(back.len(), links.len());
        }
    }
}
