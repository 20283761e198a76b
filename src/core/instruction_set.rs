//! The instruction set the hot passes run in, chosen at run time when a workspace is made.
//!
//! The library is built for the baseline x86-64 target (SSE2), which every x86-64 processor
//! runs. Intel's processors since 2013 (Haswell) and AMD's since 2015 (Excavator, then Zen) also
//! have AVX2's 256-bit registers and three-operand instructions (`x86-64-v3`); the passes of
//! ABA, of the derivatives and of the sparse factorisation take less time compiled for them
//! (docs/performance.md). A pass whose body runs through [`InstructionSet::run`] is compiled
//! twice, once per set, and runs the copy of the workspace's set; whatever the pass inlines is
//! compiled into both copies.
//!
//! Processors with AVX-512 (`x86-64-v4`) run those same AVX2 copies: with 512-bit registers
//! the compiler's code for the passes took as long or longer (docs/performance.md). A pass with
//! long loops over whole columns (the products of `aba_derivatives` on a large model) runs
//! through [`InstructionSet::run_wide`] instead, which has a third copy compiled with AVX-512,
//! where a loop can hold a whole column of fifty rows in registers.
//!
//! **The fused copies compute the same bits.** A pass that asks for it receives its copy's
//! [`MulAdd`]: the AVX2 and AVX-512 copies round a multiply-add once (fused), the baseline twice
//! (it has no fused instruction). Otherwise Rust neither contracts a multiplication and an
//! addition nor reorders floating-point operations, whatever the target features, so the AVX2
//! and AVX-512 copies perform the same IEEE operations and agree bit for bit, and the baseline
//! agrees with them to within rounding (a test holds every dispatched kernel to both).

use crate::mul_add::MulAdd;
use crate::{Model, Workspace};

/// The instruction set a workspace's passes run in
/// ([`Workspace::instruction_set`](crate::Workspace::instruction_set)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InstructionSet {
    /// The baseline of the build target (SSE2 on x86-64): runs everywhere.
    Baseline,
    /// AVX2 and FMA (`x86-64-v3`), on a processor that has them ([`X86V3`]).
    #[cfg(target_arch = "x86_64")]
    X86V3(X86V3),
    /// AVX-512 (`x86-64-v4`: F, DQ, VL, BW and CD, with AVX2 and FMA), on a processor that has
    /// it ([`X86V4`]): the AVX2 copies, and the AVX-512 copies of the passes run through
    /// [`InstructionSet::run_wide`].
    #[cfg(target_arch = "x86_64")]
    X86V4(X86V4),
}

/// Proof that the processor runs AVX2 and FMA: made only by [`InstructionSet::best`] after the
/// processor said so, which is what makes running the [`InstructionSet::X86V3`] copies sound.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct X86V3 {
    detected: (),
}

/// Proof that the processor runs AVX-512 (F, DQ, VL, BW, CD) besides AVX2 and FMA: made only
/// by [`InstructionSet::best`] after the processor said so, which is what makes running the
/// [`InstructionSet::X86V4`] copies sound.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct X86V4 {
    v3: X86V3,
}

impl InstructionSet {
    /// The fastest set this processor runs: [`InstructionSet::X86V4`] where it has AVX-512,
    /// [`InstructionSet::X86V3`] where it has AVX2 and FMA, else [`InstructionSet::Baseline`].
    pub fn best() -> InstructionSet {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            let v3 = X86V3 { detected: () };
            let avx512 = std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512bw")
                && std::arch::is_x86_feature_detected!("avx512cd");
            return if avx512 {
                InstructionSet::X86V4(X86V4 { v3 })
            } else {
                InstructionSet::X86V3(v3)
            };
        }
        InstructionSet::Baseline
    }

    /// Every set this processor runs, the baseline first and [`best`](Self::best) last.
    pub fn available() -> Vec<InstructionSet> {
        let mut sets = vec![InstructionSet::Baseline];
        #[cfg(target_arch = "x86_64")]
        match InstructionSet::best() {
            InstructionSet::X86V4(v4) => {
                sets.extend([InstructionSet::X86V3(v4.v3), InstructionSet::X86V4(v4)])
            }
            best @ InstructionSet::X86V3(_) => sets.push(best),
            InstructionSet::Baseline => {}
        }
        sets
    }

    /// The set's name: `baseline`, `x86-64-v3` or `x86-64-v4`.
    pub fn name(self) -> &'static str {
        match self {
            InstructionSet::Baseline => "baseline",
            #[cfg(target_arch = "x86_64")]
            InstructionSet::X86V3(_) => "x86-64-v3",
            #[cfg(target_arch = "x86_64")]
            InstructionSet::X86V4(_) => "x86-64-v4",
        }
    }

    /// Whether [`run_wide`](Self::run_wide) has a copy of its own in this set (AVX-512).
    pub(crate) fn is_wide(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        if let InstructionSet::X86V4(_) = self {
            return true;
        }
        false
    }

    /// `pass(model, ws, args)` through the set's copy of it, each `pass` compiled as a function
    /// of its own for its set: `baseline` ([`run_pass`] defines it in the pass's module) or
    /// [`x86_64_v3`]. The model, the workspace and the arguments are the copy's own parameters,
    /// so the compiler knows, as it does for any function taking `&mut Workspace`, that nothing
    /// else writes the workspace meanwhile.
    #[inline(always)]
    pub(crate) fn run<A, R, P: FnOnce(&Model, &mut Workspace, A, MulAdd) -> R>(
        self,
        model: &Model,
        ws: &mut Workspace,
        args: A,
        pass: P,
        baseline: fn(&Model, &mut Workspace, A, P) -> R,
    ) -> R {
        match self {
            InstructionSet::Baseline => baseline(model, ws, args, pass),
            #[cfg(target_arch = "x86_64")]
            InstructionSet::X86V3(_) | InstructionSet::X86V4(_) => {
                // SAFETY: an `X86V3` or `X86V4` exists only where `best` found AVX2 and FMA.
                #[allow(unsafe_code)]
                unsafe {
                    x86_64_v3(model, ws, args, pass)
                }
            }
        }
    }

    /// [`run`](Self::run), but in the AVX-512 copy ([`x86_64_v4`]) where the set is
    /// [`InstructionSet::X86V4`] ([`run_wide_pass`]).
    #[inline(always)]
    pub(crate) fn run_wide<A, R, P: FnOnce(&Model, &mut Workspace, A, MulAdd) -> R>(
        self,
        model: &Model,
        ws: &mut Workspace,
        args: A,
        pass: P,
        baseline: fn(&Model, &mut Workspace, A, P) -> R,
    ) -> R {
        match self {
            #[cfg(target_arch = "x86_64")]
            InstructionSet::X86V4(_) => {
                // SAFETY: an `X86V4` exists only where `best` found AVX-512, AVX2 and FMA.
                #[allow(unsafe_code)]
                unsafe {
                    x86_64_v4(model, ws, args, pass)
                }
            }
            _ => self.run(model, ws, args, pass, baseline),
        }
    }
}

/// `run_pass!(pass(model, ws, args…))`: `pass(model, ws, args…)` in `ws`'s instruction set
/// ([`InstructionSet::run`]), `pass` taking the model, the workspace and any further arguments
/// (plain identifiers). `pass` is inlined into each of the set's copies.
/// `run_pass!(pass(model, ws, args…; mul_add))` also passes the copy's [`MulAdd`] last, a
/// constant in each copy ([`MulAdd::SEPARATE`] in the baseline, [`MulAdd::FUSED`] in the
/// others).
///
/// The baseline copy is a generic function defined where the macro is used: the compiler
/// places a generic function's instances in the codegen unit of the module that defines it, so
/// it sits with the pass's own module. There the helpers the pass calls (not `#[inline]`) can
/// be inlined, and those left out of line carry what the optimiser learned about them (which
/// arguments they only read), as in a pass not dispatched. The AVX2 copy stays in this
/// module ([`x86_64_v3`]): placed with the pass, the optimiser packs ABA's articulated pass
/// into lane-crossing 256-bit shuffles (`vperm2f128`, `vpermpd`, `vinsertf128`), fewer
/// instructions that take longer: `fd_aba` 3–5 % slower on UR5, Solo12 and TALOS (same-run
/// A/B on the benchmark machine's AMD EPYC, 2026-11-27).
macro_rules! run_pass {
    ($pass:ident($model:ident, $ws:ident $(, $arg:ident)* $(,)?)) => {
        $crate::instruction_set::run_pass!(run, $pass($model, $ws $(, $arg)*))
    };
    ($pass:ident($model:ident, $ws:ident $(, $arg:ident)*; $mul_add:ident)) => {
        $crate::instruction_set::run_pass!(run, $pass($model, $ws $(, $arg)*; $mul_add))
    };
    ($run:ident, $pass:ident($model:ident, $ws:ident $(, $arg:ident)* $(,)?)) => {
        $crate::instruction_set::run_pass!(@in $run, $pass($model, $ws $(, $arg)*), _, [])
    };
    ($run:ident, $pass:ident($model:ident, $ws:ident $(, $arg:ident)*; $mul_add:ident)) => {
        $crate::instruction_set::run_pass!(@in $run, $pass($model, $ws $(, $arg)*), $mul_add, [$mul_add])
    };
    (@in $run:ident, $pass:ident($model:ident, $ws:ident $(, $arg:ident)*), $mul_add:pat,
        [$($passed:ident)?]) => {{
        /// The pass compiled for the build target.
        #[inline(never)]
        fn baseline<
            A,
            R,
            P: FnOnce(&$crate::Model, &mut $crate::Workspace, A, $crate::mul_add::MulAdd) -> R,
        >(
            model: &$crate::Model,
            ws: &mut $crate::Workspace,
            args: A,
            pass: P,
        ) -> R {
            pass(model, ws, args, $crate::mul_add::MulAdd::SEPARATE)
        }

        $ws.plan.instruction_set.$run(
            $model,
            $ws,
            ($($arg,)*),
            #[inline(always)]
            |$model, $ws, ($($arg,)*), $mul_add: $crate::mul_add::MulAdd| {
                $pass($model, $ws $(, $arg)* $(, $passed)?)
            },
            baseline,
        )
    }};
}
pub(crate) use run_pass;

/// `run_wide_pass!(pass(model, ws, args…))`: [`run_pass`] through
/// [`InstructionSet::run_wide`], so that `pass` has an AVX-512 copy too.
macro_rules! run_wide_pass {
    ($pass:ident($model:ident, $ws:ident $(, $arg:ident)* $(,)?)) => {
        $crate::instruction_set::run_pass!(run_wide, $pass($model, $ws $(, $arg)*))
    };
    ($pass:ident($model:ident, $ws:ident $(, $arg:ident)*; $mul_add:ident)) => {
        $crate::instruction_set::run_pass!(run_wide, $pass($model, $ws $(, $arg)*; $mul_add))
    };
}
pub(crate) use run_wide_pass;

/// The pass compiled with AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn x86_64_v3<A, R>(
    model: &Model,
    ws: &mut Workspace,
    args: A,
    pass: impl FnOnce(&Model, &mut Workspace, A, MulAdd) -> R,
) -> R {
    pass(model, ws, args, MulAdd::FUSED)
}

/// The pass compiled with AVX-512 (and AVX2 and FMA).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512dq,avx512vl,avx512bw,avx512cd")]
#[inline(never)]
fn x86_64_v4<A, R>(
    model: &Model,
    ws: &mut Workspace,
    args: A,
    pass: impl FnOnce(&Model, &mut Workspace, A, MulAdd) -> R,
) -> R {
    pass(model, ws, args, MulAdd::FUSED)
}
