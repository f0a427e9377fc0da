//! The indexed heap against a naive model (a map from cell to key and payload, minimum found by scanning).

use std::collections::BTreeMap;

use cfnav::nav::queue::{IndexedQueue, Key, QueueFull};
use proptest::prelude::*;

#[derive(Debug, Clone)]
enum Op {
    Push(usize, u32, u16, u16),
    Update(usize, u32, u16, u16),
    Remove(usize),
    Pop,
    Clear,
}

fn op() -> impl Strategy<Value = Op> {
    let cell = 0usize..70; // some ids beyond CELLS = 64 exercise the "ignored" path
    // Mostly small keys (many ties), sometimes any key (the sifts compare k1 and k2 packed in one integer).
    let k1 = prop_oneof![4 => 0u32..50, 1 => any::<u32>()];
    let k2 = prop_oneof![4 => 0u16..5, 1 => any::<u16>()];
    prop_oneof![
        4 => (cell.clone(), k1.clone(), k2.clone(), any::<u16>()).prop_map(|(c, a, b, p)| Op::Push(c, a, b, p)),
        3 => (cell.clone(), k1, k2, any::<u16>()).prop_map(|(c, a, b, p)| Op::Update(c, a, b, p)),
        2 => cell.prop_map(Op::Remove),
        2 => Just(Op::Pop),
        1 => Just(Op::Clear),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn behaves_like_the_model(ops in proptest::collection::vec(op(), 1..200)) {
        const CELLS: usize = 64;
        const CAP: usize = 40; // three levels of the 4-ary heap and part of a fourth
        let mut q: IndexedQueue<CELLS, CAP> = IndexedQueue::new();
        let mut model: BTreeMap<usize, (Key, u16)> = BTreeMap::new();
        for op in ops {
            match op {
                Op::Push(c, k1, k2, p) => {
                    let key = Key { k1, k2 };
                    let r = q.push(c, key, p);
                    if c >= CELLS {
                        prop_assert_eq!(r, Ok(()));
                    } else if model.contains_key(&c) || model.len() < CAP {
                        prop_assert_eq!(r, Ok(()));
                        model.insert(c, (key, p));
                    } else {
                        prop_assert_eq!(r, Err(QueueFull));
                    }
                }
                Op::Update(c, k1, k2, p) => {
                    q.update(c, Key { k1, k2 }, p);
                    if let Some(e) = model.get_mut(&c) {
                        *e = (Key { k1, k2 }, p);
                    }
                }
                Op::Remove(c) => {
                    prop_assert_eq!(q.remove(c), model.remove(&c).map(|(_, p)| p));
                }
                Op::Pop => {
                    let got = q.pop();
                    let min = model.values().map(|(k, _)| *k).min();
                    match (got, min) {
                        (None, None) => {}
                        (Some((c, k, p)), Some(m)) => {
                            prop_assert_eq!(k, m);
                            prop_assert_eq!(model.remove(&c), Some((k, p)));
                        }
                        (g, m) => prop_assert!(false, "pop {:?} vs model min {:?}", g, m),
                    }
                }
                Op::Clear => {
                    q.clear();
                    model.clear();
                }
            }
            prop_assert_eq!(q.len(), model.len());
            prop_assert_eq!(q.top_key(), model.values().map(|(k, _)| *k).min().unwrap_or(Key::MAX));
            for c in 0..CELLS {
                prop_assert_eq!(q.contains(c), model.contains_key(&c));
                prop_assert_eq!(q.payload(c), model.get(&c).map(|(_, p)| *p));
            }
        }
    }
}

#[test]
fn rekey_restores_heap_order() {
    let mut q: IndexedQueue<32, 32> = IndexedQueue::new();
    for c in 0..32 {
        q.push(c, Key { k1: c as u32, k2: 0 }, c as u16).unwrap();
    }
    // Reverse every key.
    q.rekey(|c, _| Key {
        k1: 100 - c as u32,
        k2: 0,
    });
    let mut popped = Vec::new();
    while let Some((c, k, p)) = q.pop() {
        assert_eq!(k.k1, 100 - c as u32);
        assert_eq!(usize::from(p), c);
        popped.push(c);
    }
    assert_eq!(popped, (0..32).rev().collect::<Vec<_>>());
}
