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
    pub fn new(n: usize, pairs: impl Iterator<Item = (usize, T)>) -> Adjacency<T>
    where
        T: Copy,
    {
        let pairs: Vec<(usize, T)> = pairs.collect();
        // (Counted per node, then placed in the order given: a stable bucket sort.)
        let mut starts = vec![0u32; n + 1];
        for &(node, _) in &pairs {
            starts[node + 1] += 1;
        }
        for i in 0..n {
            starts[i + 1] += starts[i];
        }
        // Which pair goes to each place.
        let mut next: Vec<u32> = starts[..n].to_vec();
        let mut from = vec![0u32; pairs.len()];
        for (i, &(node, _)) in pairs.iter().enumerate() {
            from[next[node] as usize] = i as u32;
            next[node] += 1;
        }
        let items = from.iter().map(|&i| pairs[i as usize].1).collect();
        Adjacency { starts, items }
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
