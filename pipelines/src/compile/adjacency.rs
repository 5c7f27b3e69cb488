//! Adjacency lists of a dependence graph in one allocation: every node's items side by side,
//! in the order they were given (compressed sparse rows). The schedulers build a region's
//! predecessor and successor lists for every schedule they try.

use std::ops::Index;

/// Per node, the items given for it, in the order given.
pub struct Adjacency<T> {
    /// Where each node's items start in `items`, and (last) where the items end.
    starts: Vec<u32>,
    items: Vec<T>,
}

impl<T> Adjacency<T> {
    /// The lists of nodes `0..n`, from `(node, item)` pairs.
    pub fn new(n: usize, pairs: impl Iterator<Item = (usize, T)>) -> Adjacency<T> {
        let mut pairs: Vec<(usize, T)> = pairs.collect();
        // (A stable sort: each node's items stay in the order given.)
        pairs.sort_by_key(|&(node, _)| node);
        let mut starts = vec![0u32; n + 1];
        for &(node, _) in &pairs {
            starts[node + 1] += 1;
        }
        for i in 0..n {
            starts[i + 1] += starts[i];
        }
        Adjacency {
            starts,
            items: pairs.into_iter().map(|(_, item)| item).collect(),
        }
    }
}

impl<T> Index<usize> for Adjacency<T> {
    type Output = [T];

    fn index(&self, node: usize) -> &[T] {
        &self.items[self.starts[node] as usize..self.starts[node + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::Adjacency;

    #[test]
    fn lists_keep_each_nodes_items_in_the_order_given() {
        let pairs = [(2, 'a'), (0, 'b'), (2, 'c'), (3, 'd'), (0, 'e')];
        let lists = Adjacency::new(4, pairs.iter().copied());
        assert_eq!(&lists[0], &['b', 'e']);
        assert!(lists[1].is_empty());
        assert_eq!(&lists[2], &['a', 'c']);
        assert_eq!(&lists[3], &['d']);
    }
}
