//! The dynamics kernels documented as allocation-free do not allocate: a
//! counting global allocator (its own test binary) counts the allocations
//! made on this thread while each kernel runs, after one warm-up call, for
//! robots with and without coupling, rotor inertia and friction.

use idexp::robot::{self, Workspace};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ON: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

fn note() {
    // try_with: the thread-locals may be gone while a thread exits
    if ON.try_with(|o| o.get()).unwrap_or(false) {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc(l) }
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc_zeroed(l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        note();
        unsafe { System.realloc(p, l, n) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static A: Counting = Counting;

/// Allocations made on this thread by `f`.
fn allocations(f: impl FnOnce()) -> usize {
    COUNT.with(|c| c.set(0));
    ON.with(|o| o.set(true));
    f();
    ON.with(|o| o.set(false));
    COUNT.with(|c| c.get())
}

#[test]
fn dynamics_kernels_do_not_allocate() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in ["ur5", "panda", "puma560", "industrial6", "iiwa14"] {
        let r = robot::load(&root.join(format!("designs/robots/{name}.toml"))).unwrap();
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let theta = r.nominal_params();
        let theta = theta.as_slice();
        let q: Vec<f64> = (0..n).map(|i| 0.4 * i as f64 - 0.9).collect();
        let qd: Vec<f64> = (0..n).map(|i| 0.3 - 0.15 * i as f64).collect();
        let qdd: Vec<f64> = (0..n).map(|i| (1.7 * i as f64).sin()).collect();
        let mut tau = vec![0.0; n];
        let mut m = nalgebra::DMatrix::zeros(n, n);
        let mut y = vec![0.0; n * p];
        let mut dq = vec![vec![0.0; n * p]; n];
        let mut dqd = dq.clone();
        let mut dqdd = dq.clone();
        let (mut qs, mut qds) = (q.clone(), qd.clone());
        let (mut gq, mut gqd) = (nalgebra::DMatrix::zeros(n, n), nalgebra::DMatrix::zeros(n, n));
        let mut run = |ws: &mut Workspace| {
            robot::rnea(&r, ws, &q, &qd, &qdd, &mut tau);
            robot::inverse_dynamics(&r, ws, theta, &q, &qd, &qdd, &mut tau);
            robot::mass_matrix_into(&r, ws, &q, &mut m);
            robot::mass_matrix_with_into(&r, ws, theta, &q, &mut m);
            robot::forward_dynamics_into(&r, ws, &q, &qd, &qdd, &mut tau).unwrap();
            robot::rk4_step(&r, ws, &mut qs, &mut qds, &qdd, 1e-3, |_| Ok(()), |e| e).unwrap();
            robot::regressor_rows(&r, ws, &q, &qd, &qdd, &mut y);
            robot::regressor_derivatives(&r, ws, &q, &qd, &qdd, &mut y, &mut dq, &mut dqd, &mut dqdd);
            robot::dynamics::id_derivatives_into(&r, ws, theta, &q, &qd, &qdd, &mut gq, &mut gqd);
        };
        run(&mut ws); // warm-up
        let k = allocations(|| run(&mut ws));
        assert_eq!(k, 0, "{name}: {k} allocations in the allocation-free kernels");
    }
}

/// The counter sees allocations (the test above is not vacuous).
#[test]
fn the_counter_counts() {
    let k = allocations(|| {
        std::hint::black_box(vec![1.0_f64; 10]);
    });
    assert!(k >= 1);
}
