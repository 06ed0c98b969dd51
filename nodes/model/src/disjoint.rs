//! Disjoint sets (union–find) over `0..n`, each set named by its smallest member so that results do not depend
//! on the order of the unions.

pub struct Disjoint {
    parent: Vec<usize>,
}

impl Disjoint {
    pub fn new(n: usize) -> Self {
        Disjoint { parent: (0..n).collect() }
    }

    /// The smallest member of `v`'s set.
    pub fn root(&mut self, mut v: usize) -> usize {
        while self.parent[v] != v {
            self.parent[v] = self.parent[self.parent[v]];
            v = self.parent[v];
        }
        v
    }

    pub fn join(&mut self, a: usize, b: usize) {
        let (a, b) = (self.root(a), self.root(b));
        self.parent[a.max(b)] = a.min(b);
    }
}
