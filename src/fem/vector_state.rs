//! Leaving faer's dense kernels with clean vector registers.
//!
//! faer's matrix products run hand-written x86-64 kernels (the `private-gemm-x86` crate)
//! that use 512-bit registers and return without `vzeroupper`. Until the thread's next
//! `vzeroupper`, every SSE instruction of the code it runs next pays for the registers' dirty
//! upper halves: this crate is compiled for baseline x86-64, so all of its floating point
//! outside faer is SSE. Measured on `run`: the surface scoring after the deformable stage took
//! 0.84-0.89 s instead of 0.54-0.56 s (BENCHMARKS.md, "Dirty vector registers").
//!
//! A [`DenseKernels`] guard is held across each call into faer's numeric factorisations and
//! solves and clears the registers when dropped: the calling thread at once, and, after a
//! call that may have run kernels on rayon's other workers, each of them when it next looks
//! for work (`rayon::spawn_broadcast`: no thread waits for a worker busy elsewhere).

/// Clears the vector registers' upper halves when dropped (module documentation).
pub(crate) struct DenseKernels {
    /// Whether faer may have run kernels on other threads (a parallel call).
    parallel: bool,
}

impl DenseKernels {
    /// For a call that faer runs on the calling thread alone (`Par::Seq`).
    pub(crate) fn sequential() -> Self {
        DenseKernels { parallel: false }
    }

    /// For a call with faer's global parallelism, which may use every rayon worker.
    pub(crate) fn parallel() -> Self {
        DenseKernels { parallel: true }
    }
}

impl Drop for DenseKernels {
    fn drop(&mut self) {
        clear_this_thread();
        if self.parallel {
            rayon::spawn_broadcast(|_| clear_this_thread());
        }
    }
}

/// `vzeroupper` on this thread, where the processor has AVX (otherwise no instruction has
/// written the upper halves).
fn clear_this_thread() {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the instruction needs AVX, which the processor was just found to have;
        // it only zeroes bits 128 and above of the vector registers, which no code relies on
        // across a function return (the x86-64 calling convention).
        unsafe { std::arch::x86_64::_mm256_zeroupper() }
    }
}

#[cfg(target_arch = "x86_64")]
#[cfg(test)]
mod tests {
    use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
    use faer::{Accum, Mat, Par};

    use super::*;
    use crate::fem::cholesky::SparseCholesky;

    /// The components of the calling thread's vector registers not in their initial state
    /// (XGETBV with ECX = 1, "XINUSE"): bit 2 the upper halves of the 256-bit registers,
    /// bit 6 the upper halves of the 512-bit ones.
    fn dirty_upper_halves() -> u64 {
        assert!(
            std::arch::is_x86_feature_detected!("avx")
                && std::arch::is_x86_feature_detected!("xsave"),
            "these tests need a processor with AVX"
        );
        // CPUID.(EAX = 0Dh, ECX = 1):EAX bit 2: XGETBV with ECX = 1 is supported
        let leaf = std::arch::x86_64::__cpuid_count(0xd, 1);
        assert!(
            leaf.eax & 0b100 != 0,
            "these tests need XGETBV with ECX = 1"
        );
        // SAFETY: XSAVE and XGETBV with ECX = 1 are supported (both asserted above).
        let in_use = unsafe { std::arch::x86_64::_xgetbv(1) };
        in_use & 0b100_0100
    }

    /// A product of two 200 x 200 matrices on the calling thread (faer's hand-written kernels).
    fn faer_product() -> f64 {
        let a = Mat::<f64>::from_fn(200, 200, |i, j| ((7 * i + j) % 13) as f64);
        let mut c = Mat::<f64>::zeros(200, 200);
        faer::linalg::matmul::matmul(
            c.as_mut(),
            Accum::Replace,
            a.as_ref(),
            a.as_ref(),
            1.0,
            Par::Seq,
        );
        c[(3, 5)]
    }

    /// The premise, and the remedy: faer's product leaves the upper halves dirty (were this to
    /// fail, faer has been fixed and this module can go), and `DenseKernels` cleans them.
    #[test]
    fn faer_leaves_the_upper_halves_dirty_and_the_guard_clears_them() {
        assert!(faer_product() > 0.0);
        assert_ne!(dirty_upper_halves(), 0);
        drop(DenseKernels::sequential());
        assert_eq!(dirty_upper_halves(), 0);
    }

    /// A sparse Cholesky factorisation and solve (supernodal, its updates in faer's kernels on
    /// rayon's workers) leave the calling thread and every worker clean, though each was
    /// dirtied beforehand, whether called from outside rayon's pool or from one of its workers. Run in a process of its own (this test binary again,
    /// this test alone), so that no other test dirties a worker in between.
    #[test]
    fn a_factorisation_leaves_every_thread_clean() {
        const ALONE: &str = "OTOATLAS_VECTOR_STATE_TEST_ALONE";
        if std::env::var_os(ALONE).is_none() {
            let name = module_path!()
                .split_once("::")
                .map_or("", |(_, path)| path)
                .to_string()
                + "::a_factorisation_leaves_every_thread_clean";
            let output = std::process::Command::new(std::env::current_exe().unwrap())
                .args([name.as_str(), "--exact", "--test-threads=1"])
                .env(ALONE, "1")
                .output()
                .unwrap();
            let stdout = String::from_utf8_lossy(&output.stdout);
            assert!(
                output.status.success() && stdout.contains("1 passed"),
                "{stdout}{}",
                String::from_utf8_lossy(&output.stderr)
            );
            return;
        }
        // the lower triangle of a 7-point Laplacian on a 14^3 grid, shifted
        let side = 14usize;
        let n = side * side * side;
        let index = |x: usize, y: usize, z: usize| x + side * (y + side * z);
        let (mut col_ptr, mut rows, mut values) = (vec![0usize], Vec::new(), Vec::new());
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    rows.push(index(x, y, z));
                    values.push(6.1);
                    for (dx, dy, dz) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                        let (u, v, w) = (x + dx, y + dy, z + dz);
                        if u < side && v < side && w < side {
                            rows.push(index(u, v, w));
                            values.push(-1.0);
                        }
                    }
                    col_ptr.push(rows.len());
                }
            }
        }
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows);
        let mut cholesky = SparseCholesky::analyse_in_order(pattern.as_ref()).unwrap();
        let mut rhs = vec![1.0; n];
        // every thread dirty, then each call, then the threads still dirty (the calling thread
        // is one of the pool's inside it)
        let mut calls_and_count = |inside: bool| {
            let dirty_everywhere = || {
                faer_product();
                rayon::broadcast(|_| {
                    faer_product();
                });
            };
            let dirty_threads = || {
                let mut d = rayon::broadcast(|_| dirty_upper_halves());
                if !inside {
                    d.push(dirty_upper_halves());
                }
                d.into_iter().filter(|&bits| bits != 0).count()
            };
            dirty_everywhere();
            let all = dirty_threads();
            cholesky
                .factorise(SparseColMatRef::new(pattern.as_ref(), &values))
                .unwrap();
            let after_factorisation = dirty_threads();
            dirty_everywhere();
            rhs.fill(1.0);
            cholesky.solve_in_place(&mut rhs).unwrap();
            [all, after_factorisation, dirty_threads()]
        };
        // from outside rayon's pool (the test's thread), then from one of its workers
        let threads = rayon::current_num_threads();
        assert_eq!(calls_and_count(false), [threads + 1, 0, 0]);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        assert_eq!(pool.install(|| calls_and_count(true)), [2, 0, 0]);
        // the solve is a solve: A x = 1 at an interior unknown
        let c = index(7, 7, 7);
        let neighbours = [1, side, side * side]
            .iter()
            .map(|&s| rhs[c - s] + rhs[c + s])
            .sum::<f64>();
        assert!((6.1 * rhs[c] - neighbours - 1.0).abs() < 1e-10);
    }
}
