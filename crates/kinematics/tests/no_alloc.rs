//! Numeric FK and its Jacobians allocate nothing per call (counting global allocator).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use armature_kinematics::robots;
use nalgebra::{Matrix3xX, Matrix6xX, Vector3};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    static WATCHING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if WATCHING.with(|w| w.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn forward_and_jacobians_do_not_allocate() {
    for chain in [robots::arm7(), robots::ur5e()] {
        let n = chain.dof();
        let mut ws = chain.fk_workspace();
        let mut body = Matrix6xX::zeros(n);
        let mut pj = Matrix3xX::zeros(n);
        let mut q = vec![0.3; n];
        let before = ALLOCATIONS.load(Ordering::SeqCst);
        WATCHING.with(|w| w.set(true));
        for k in 0..200 {
            q[k % n] += 0.01;
            chain.forward(&q, &mut ws).unwrap();
            ws.body_jacobian(&mut body).unwrap();
            let p = ws.keypoint_position(1);
            ws.point_jacobian(chain.keypoints()[1].after, &p, &mut pj).unwrap();
            std::hint::black_box(ws.point_on_link(2, &Vector3::new(0.1, 0.0, 0.0)));
        }
        WATCHING.with(|w| w.set(false));
        assert_eq!(ALLOCATIONS.load(Ordering::SeqCst) - before, 0, "{}", chain.name());
    }
    WATCHING.with(|w| w.set(true));
    drop(std::hint::black_box(vec![0u8; 16]));
    WATCHING.with(|w| w.set(false));
    assert!(ALLOCATIONS.load(Ordering::SeqCst) > 0, "the counter sees allocations");
}
