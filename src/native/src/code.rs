//! Executable memory and the call into it: the crate's one module with `unsafe`.
//!
//! Cranelift's JIT module writes the generated function into memory it maps writable, then
//! makes it readable and executable (never both writable and executable) and flushes the
//! instruction cache where the processor needs it. [`Code`] owns that memory for as long as
//! the program it belongs to lives, and calls the function with a [`Context`] built from the
//! borrowed memory of one [`NativeCode::run`].

#![allow(unsafe_code)]

use cranelift_codegen::control::ControlPlane;
use cranelift_codegen::ir::{types, AbiParam, Function, Signature};
use cranelift_codegen::isa::{CallConv, TargetIsa};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, FuncId, Linkage, Module, ModuleReloc};
use plcd_core::lang::native::{
    IlFrame, IlMemory, NativeCode, NativeExit, NativeMemory, NativeMemoryOffsets, NativeRegs,
};
use plcd_core::lang::Program;
use plcd_core::vm::Clock;

use crate::{analysis, codegen, il, Error};

/// What the code was compiled from, and what its analysis says the interpreter's share is.
pub(crate) enum Shape {
    StructuredText(analysis::Analysis),
    InstructionList(il::Analysis),
}

impl Shape {
    fn words_end(&self) -> u64 {
        match self {
            Shape::StructuredText(a) => a.words_end,
            Shape::InstructionList(a) => a.words_end,
        }
    }

    /// What the instruction list's state must hold for the code (`None` for Structured Text).
    fn il_needs(&self) -> Option<IlNeeds> {
        match self {
            Shape::StructuredText(_) => None,
            Shape::InstructionList(a) => {
                Some(IlNeeds { edges: a.edges_end, timers: a.timers_end, counters: a.counters_end })
            }
        }
    }

    fn span(&self, pc: u32) -> u32 {
        match self {
            Shape::StructuredText(a) => a.span(pc),
            Shape::InstructionList(a) => a.span(pc),
        }
    }

    /// The generated function to enter at `pc`: the Structured Text body that holds it, or
    /// the instruction-list piece whose range holds it (its dispatch hands a pc that is no
    /// leader to the interpreter).
    #[inline]
    fn entry_index(&self, pc: u32) -> usize {
        match self {
            Shape::StructuredText(a) => a.function_of(pc),
            Shape::InstructionList(a) => a.piece_holding(pc),
        }
    }

    /// The number of generated functions.
    fn functions(&self) -> usize {
        match self {
            Shape::StructuredText(a) => a.functions.len(),
            Shape::InstructionList(a) => a.pieces.len() + a.subroutines.len(),
        }
    }

    fn blocks(&self) -> usize {
        match self {
            Shape::StructuredText(a) => a.leaders.len(),
            Shape::InstructionList(a) => a.leaders.len(),
        }
    }
}

/// The edge slots, timers and counters instruction-list code reaches at its fixed operands.
struct IlNeeds {
    edges: u64,
    timers: u64,
    counters: u64,
}

impl IlNeeds {
    /// Whether `il` holds them all.
    fn fit(&self, il: &IlMemory<'_>) -> bool {
        il.edges.len() as u64 >= self.edges
            && il.timers.len() as u64 >= self.timers
            && il.counters.len() as u64 >= self.counters
    }
}

/// What the generated function works on: the VM's [`NativeMemory`] of the call, in place
/// (its fields where [`CONTEXT`] says), with the registers, the instruction list's
/// [`IlContext`] and the stack floor [`Code::run`] sets in it.
pub(crate) type Context<'a> = NativeMemory<'a>;

/// The offsets of the [`Context`]'s fields.
pub(crate) const CONTEXT: NativeMemoryOffsets = NativeMemory::OFFSETS;

/// Bytes of machine stack the generated code of one [`Code::run`] may use: its calls nest
/// up to `ST_CALL_DEPTH` deep, each in a frame of its function's size. The real-time threads
/// prefault 256 KiB of their stack.
pub(crate) const NATIVE_STACK: u64 = 64 * 1024;

/// Room below the deepest frame for the helpers generated code calls (`helpers`,
/// [`copy_bytes`]): Rust functions of a few locals each.
const HELPER_STACK: u64 = 4 * 1024;

/// The instruction list's state besides device memory, as raw parts: on the stack of
/// [`Code::run`] for an instruction-list program only, so that Structured Text does not pay for
/// building it. `repr(C)`, as [`Context`].
#[repr(C)]
pub(crate) struct IlContext<'a> {
    pub calls: *mut IlFrame,
    /// Edge memory: `bool`s, 0 or 1 in a byte.
    pub edges: *mut u8,
    /// The counters' states (`plcd_core::vm::counter::layout`).
    pub counters: *mut u8,
    /// The timers' states (`plcd_core::vm::timer::layout`).
    pub timers: *mut u8,
    /// The step count at which the budget is spent.
    pub stop: u64,
    /// 1 if the clock is a `StepClock` (below), which generated code computes itself; 0 if
    /// it calls [`il_now`].
    pub linear: u64,
    pub origin_ns: u64,
    pub origin_steps: u64,
    pub step_ns: u64,
    /// A timer whose budget left after its instruction is below this may take its time as
    /// `stop_ns - left * step_ns`: the clock is a `StepClock` and the timer's step is at or
    /// after its origin (0: never, the time is asked of the clock or computed the long way).
    pub fast_below: u64,
    /// The `StepClock`'s time at step `stop` (wrapping, as the timers' arithmetic).
    pub stop_ns: u64,
    /// Only [`il_now`] uses it, never generated code.
    pub clock: *const (dyn Clock + 'a),
}

impl<'a> IlContext<'a> {
    /// The raw parts of `il`, and what the code computes the time from. Inlined: built in
    /// place in [`Code::run`]'s frame, not returned and copied there.
    #[inline]
    fn new(il: &mut IlMemory<'a>) -> IlContext<'a> {
        let linear = il.clock.linear();
        IlContext {
            calls: il.calls.as_mut_ptr(),
            edges: il.edges.as_mut_ptr().cast::<u8>(),
            counters: il.counters.address(),
            timers: il.timers.address(),
            stop: il.stop,
            linear: u64::from(linear.is_some()),
            origin_ns: linear.map_or(0, |c| c.origin_ns),
            origin_steps: linear.map_or(0, |c| c.origin_steps),
            step_ns: linear.map_or(0, |c| c.step_ns),
            fast_below: linear
                .filter(|c| il.stop >= c.origin_steps)
                .map_or(0, |c| (il.stop - c.origin_steps).saturating_add(1)),
            stop_ns: linear.map_or(0, |c| {
                c.origin_ns
                    .wrapping_add(il.stop.wrapping_sub(c.origin_steps).wrapping_mul(c.step_ns))
            }),
            clock: il.clock,
        }
    }
}

/// What the generated function returns: the first three numbered as [`NativeExit`]'s
/// variants (checked below), so that telling the VM is no more than the number.
pub(crate) const RETURN_END: u32 = 0;
pub(crate) const RETURN_INTERPRET: u32 = 1;
pub(crate) const RETURN_ERROR: u32 = 2;
/// The registers' program counter is in another generated function, which is to run next: an
/// instruction-list piece ended at a leader of another piece, or a Structured Text `RETURN`
/// returned to a caller that is not native (`codegen`).
pub(crate) const RETURN_CONTINUE: u32 = 3;
/// An instruction-list subroutine's function executed its `RET`: its caller, a machine call
/// of native code, goes on after the `CALL` with the budget in the registers. Never returned
/// to the VM, which enters only pieces.
pub(crate) const RETURN_RETURNED: u32 = 4;

const _: () = assert!(
    NativeExit::End as u32 == RETURN_END
        && NativeExit::Interpret as u32 == RETURN_INTERPRET
        && NativeExit::OperationError as u32 == RETURN_ERROR
);

/// A generated function: the context, then a Structured Text body's registers when a native
/// caller calls it (`base`, `this`, call depth, stack pointer, budget left, the FB instance's
/// address), or [`FROM_VM`] and zeros when the VM enters it (the registers are in the context;
/// the instruction list's pieces take only the context, its subroutines' functions the
/// context, the budget left, and the pointers to the registers, device memory, the
/// instruction list's state, its call stack and edge memory).
type Entry = unsafe extern "C" fn(*mut Context<'_>, u64, u64, u64, u64, u64, u64) -> u32;

/// The `base` with which the VM enters a generated function: no frame's base (a `u32`).
pub(crate) const FROM_VM: u64 = u64::MAX;

/// The signature of every generated function ([`Entry`]).
pub(crate) fn entry_signature(call_conv: CallConv) -> Signature {
    let mut signature = Signature::new(call_conv);
    signature.params.extend([AbiParam::new(types::I64); 7]);
    signature.returns.push(AbiParam::new(types::I32));
    signature
}

/// Copies `n` bytes from `from` to `to`, the ranges possibly overlapping: the long copies of
/// arrays and structs, which generated code calls.
pub(crate) extern "C" fn copy_bytes(to: *mut u8, from: *const u8, n: u64) {
    // SAFETY: only generated code calls this, after checking that both ranges lie inside
    // variable memory or the frame of the `Context` of the call under way (codegen.rs,
    // `Op::Copy`); `ptr::copy` allows them to overlap.
    unsafe { std::ptr::copy(from, to, n as usize) }
}

/// The time at step `steps`, for an instruction-list timer, when the clock is not a
/// `StepClock` (the daemon's monotonic clock).
pub(crate) extern "C" fn il_now(context: *const Context<'_>, steps: u64) -> u64 {
    // SAFETY: only instruction-list code calls this, with the `Context` of the call under way,
    // whose `il` points to the `IlContext` on `Code::run`'s stack, whose `clock` is the
    // `&dyn Clock` of the `IlMemory` borrowed for that call.
    unsafe { (*(*(*context).il.cast::<IlContext<'_>>()).clock).now_ns(steps) }
}

/// A program's native code.
pub(crate) struct Code {
    /// The memory the code lives in; `None` only while it is being freed.
    module: Option<JITModule>,
    /// The generated functions: one per Structured Text body; one per piece of an
    /// instruction-list program ([`il::Analysis::pieces`]), then one per subroutine
    /// ([`il::Analysis::subroutines`]), which only generated code calls.
    entries: Vec<Entry>,
    /// The function to enter at pc 0, where every scan starts: found once, here.
    start: Entry,
    shape: Shape,
    /// Bytes of variable memory the code reaches unchecked (`codegen::generate`).
    vars_need: u64,
    /// Device words the code reaches unchecked (its analysis' `words_end`).
    words_need: u64,
    /// The instruction list's state the code reaches unchecked; `None` for Structured Text.
    il_needs: Option<IlNeeds>,
    /// Bytes of machine stack the code may use ([`NATIVE_STACK`]).
    stack: u64,
    /// Bytes of that stack kept free under the last call generated code may make: its
    /// deepest function's frame, and the helpers' ([`Context::stack_floor`]).
    stack_reserve: u64,
    name: String,
}

// SAFETY: after `compile` the module is never used again but to free its memory in `drop`,
// which takes `&mut self`; the code itself is immutable, and each call of it works only on the
// `Context` it is given, so it may run on any thread and on several at once.
unsafe impl Send for Code {}
// SAFETY: as for `Send`: shared references only call the immutable code.
unsafe impl Sync for Code {}

/// One generated function, compiled, ready to be placed in executable memory.
struct Compiled {
    bytes: Vec<u8>,
    alignment: u64,
    relocs: Vec<ModuleReloc>,
    /// Bytes of machine stack a call of it takes: its frame, the return address and the saved
    /// frame pointer.
    stack: u64,
    /// Bytes of variable memory it reaches unchecked (`codegen::generate`; 0 for the
    /// instruction list, whose analysis has it).
    vars_need: u64,
}

/// Threads that compile one program's functions at most: Cranelift's work on one function is
/// its own, so the functions of a large program compile side by side.
const COMPILE_THREADS: usize = 4;

/// Stack of a thread that compiles: Cranelift recurses deeper than the daemon's own threads'
/// stacks allow (they are sized to their need, and locked in memory).
pub(crate) const COMPILE_STACK: usize = 8 << 20;

impl Code {
    /// Compiles `program`, whose analysis is `shape`; its calls may use `stack` bytes of
    /// machine stack ([`NATIVE_STACK`]).
    pub fn compile(program: &Program, shape: Shape, stack: u64) -> Result<Code, Error> {
        let name = program.name.clone();
        let codegen_error = |message: String| Error::Codegen { program: name.clone(), message };
        let mut flags = settings::builder();
        // Cranelift's check of the IR it is given: in test builds, where a mistake of the code
        // generator must stop the test; in a release build it would add 7 % to the compile time
        // of a project.
        let verify = if cfg!(debug_assertions) { "true" } else { "false" };
        for (flag, value) in [
            ("opt_level", "speed"),
            ("use_colocated_libcalls", "false"),
            ("enable_verifier", verify),
        ] {
            flags.set(flag, value).map_err(|e| codegen_error(e.to_string()))?;
        }
        let isa = cranelift_native::builder()
            .map_err(|e| Error::Host(e.to_string()))?
            .finish(settings::Flags::new(flags))
            .map_err(|e| Error::Host(e.to_string()))?;
        let mut module = JITModule::new(JITBuilder::with_isa(isa.clone(), default_libcall_names()));
        let signature = entry_signature(isa.default_call_conv());
        let count = shape.functions();
        let ids = (0..count)
            .map(|function| {
                module
                    .declare_function(
                        &format!("plcd_program_{function}"),
                        Linkage::Local,
                        &signature,
                    )
                    .map_err(|e| codegen_error(e.to_string()))
            })
            .collect::<Result<Vec<FuncId>, Error>>()?;
        let names: Vec<u32> = ids.iter().map(|id| id.as_u32()).collect();
        let roles = match &shape {
            Shape::StructuredText(analysis) => analysis.block_roles(&program.code),
            Shape::InstructionList(_) => analysis::BlockRoles::default(),
        };
        let generate = |function: usize, func: &mut Function| match &shape {
            Shape::StructuredText(analysis) => {
                codegen::generate(program, analysis, &roles, function, &names, &*isa, func)
            }
            Shape::InstructionList(analysis) => {
                il::codegen::generate(program, analysis, function, &names, &*isa, func);
                0
            }
        };
        let compiled = compile_functions(&*isa, &ids, generate).map_err(codegen_error)?;
        let mut vars_need = 0;
        let mut deepest = 0;
        for (id, function) in ids.iter().zip(&compiled) {
            vars_need = vars_need.max(function.vars_need);
            deepest = deepest.max(function.stack);
            module
                .define_function_bytes(*id, function.alignment, &function.bytes, &function.relocs)
                .map_err(|e| codegen_error(format!("{e:?}")))?;
        }
        module
            .finalize_definitions()
            .map_err(|e| Error::Memory { program: name.clone(), message: format!("{e:#}") })?;
        let entries: Vec<Entry> = ids
            .into_iter()
            .map(|id| {
                let address = module.get_finalized_function(id);
                // SAFETY: `address` is the start of a function just finalized, whose signature
                // the code generators made `entry_signature`'s, `Entry` in the platform's C
                // calling convention; the memory stays mapped while `module` lives, which
                // `Code` owns.
                unsafe { std::mem::transmute::<*const u8, Entry>(address) }
            })
            .collect();
        let start = entries[shape.entry_index(0)];
        let stack_reserve = deepest + HELPER_STACK;
        Ok(Code {
            module: Some(module),
            entries,
            start,
            words_need: shape.words_end(),
            il_needs: shape.il_needs(),
            shape,
            vars_need,
            stack,
            stack_reserve,
            name,
        })
    }
}

impl Code {
    /// [`NativeCode::run`] of instruction-list code, once the sizes of `memory` are checked:
    /// the instruction list's state checked and built, in this frame, for the code to read.
    /// A call of its own, so that Structured Text's entry keeps none of it in its frame.
    #[inline(never)]
    fn run_il(
        &self,
        memory: &mut NativeMemory<'_>,
        il: Option<&mut IlMemory<'_>>,
        regs: &mut NativeRegs,
        needs: &IlNeeds,
    ) -> NativeExit {
        match il {
            Some(il) if needs.fit(il) => {
                let il = IlContext::new(il);
                memory.il = (&il as *const IlContext<'_>).cast();
                // `il` lives in this frame until `enter` has returned.
                self.enter(memory, regs)
            }
            _ => NativeExit::Interpret,
        }
    }

    /// Runs the code on `memory` from `regs`, once the sizes the code relies on are checked
    /// (and, for instruction-list code, its state is in `memory.il`), until it returns to the
    /// VM. Inlined into its callers: one call a run, none of its own.
    #[inline(always)]
    fn enter(&self, memory: &mut NativeMemory<'_>, regs: &mut NativeRegs) -> NativeExit {
        let pc = regs.pc;
        memory.regs = regs;
        // The floor is measured from the memory, in the caller's frame: the generated code runs
        // below it (and below this function's frame, which the bound then covers too).
        let here = std::ptr::addr_of!(*memory) as u64;
        memory.stack_floor = here.saturating_sub(self.stack) + self.stack_reserve;
        let context: *mut Context<'_> = memory;
        let entry = if pc == 0 { self.start } else { self.entries[self.shape.entry_index(pc)] };
        // SAFETY: `context` is the caller's `NativeMemory`, whose pointers come from slices it
        // borrows for its lifetime, with their lengths beside them, and `regs`, borrowed for
        // this call; its `il` is null for Structured Text code, which does not read it, and for
        // instruction-list code the `IlContext` `run_il` built from the `IlMemory` borrowed for
        // this call, in its frame, which lives until this returns. The generated code reads
        // and writes only inside those lengths: the fixed operands were checked against them
        // before (`NativeCode::run`), the frame and FB-instance operands are checked at each
        // block's entry, pointers are checked before each access, the evaluation stack is
        // indexed modulo its length and the call stack below `ST_CALL_DEPTH` (codegen.rs);
        // instruction-list code reaches device words, edge slots, timers and counters only at
        // the fixed operands checked before, and its call stack below `CALL_DEPTH`
        // (il/codegen.rs). It keeps no pointer after it returns.
        let status = unsafe { entry(context, FROM_VM, 0, 0, 0, 0, 0) };
        if status == RETURN_CONTINUE {
            return self.go_on(context);
        }
        exit_of(status)
    }

    /// After a generated function returned [`RETURN_CONTINUE`]: the function that holds the
    /// registers' `pc`, and so on until one returns something else. Not inlined: most runs
    /// (every Structured Text scan without a `RETURN` to the VM) never come here.
    #[inline(never)]
    fn go_on(&self, context: *mut Context<'_>) -> NativeExit {
        loop {
            // An instruction-list piece went on into another, or a Structured Text `RETURN`
            // returned to a caller that is not native: that one's code, with the budget the
            // first left (it is checked at each block).
            // SAFETY: the generated code has returned; the context is `enter`'s, whose `regs`
            // is the `NativeRegs` borrowed for the call of `NativeCode::run` under way, and
            // nothing else refers to it now.
            let pc = unsafe { (*(*context).regs).pc };
            let entry = self.entries[self.shape.entry_index(pc)];
            // SAFETY: as in `enter`, whose context this is, during the same call of
            // `NativeCode::run` (its `IlContext`, if any, in `run_il`'s frame, still there).
            let status = unsafe { entry(context, FROM_VM, 0, 0, 0, 0, 0) };
            if status != RETURN_CONTINUE {
                return exit_of(status);
            }
        }
    }
}

/// What the VM is told of a generated function's return `status` (not [`RETURN_CONTINUE`]):
/// the three statuses it may see are numbered as [`NativeExit`]'s variants, so this is the
/// status itself where it is one of them.
#[inline(always)]
fn exit_of(status: u32) -> NativeExit {
    match status {
        RETURN_END => NativeExit::End,
        RETURN_INTERPRET => NativeExit::Interpret,
        RETURN_ERROR => NativeExit::OperationError,
        // What no generated function returns to the VM.
        _ => NativeExit::Interpret,
    }
}

/// Generates and compiles the functions `ids` (`generate` fills function `i` and returns
/// what it reaches unchecked), on up to [`COMPILE_THREADS`] threads; the results in the order
/// of `ids`.
fn compile_functions(
    isa: &dyn TargetIsa,
    ids: &[FuncId],
    generate: impl Fn(usize, &mut Function) -> u64 + Sync,
) -> Result<Vec<Compiled>, String> {
    let compile_one = |function: usize| -> Result<Compiled, String> {
        let mut func = Function::new();
        let vars_need = generate(function, &mut func);
        let mut context = cranelift_codegen::Context::for_function(func);
        context.compile(isa, &mut ControlPlane::default()).map_err(|e| format!("{:?}", e.inner))?;
        let code = context.compiled_code().ok_or("Cranelift compiled no code")?;
        let relocs = code
            .buffer
            .relocs()
            .iter()
            .map(|reloc| ModuleReloc::from_mach_reloc(reloc, &context.func, ids[function]))
            .collect();
        let frame = code.buffer.frame_layout().map_or(0, |f| u64::from(f.frame_to_fp_offset));
        Ok(Compiled {
            bytes: code.code_buffer().to_vec(),
            alignment: u64::from(code.buffer.alignment),
            relocs,
            // The frame below the frame pointer, the saved frame pointer, the return address.
            stack: frame + 16,
            vars_need,
        })
    };
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(COMPILE_THREADS)
        .min(ids.len());
    if threads <= 1 {
        return (0..ids.len()).map(compile_one).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new((0..ids.len()).map(|_| None).collect::<Vec<_>>());
    std::thread::scope(|scope| {
        let work = || loop {
            let function = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if function >= ids.len() {
                return;
            }
            let result = compile_one(function);
            results.lock().unwrap_or_else(|e| e.into_inner())[function] = Some(result);
        };
        let helpers: Vec<_> = (1..threads)
            .filter_map(|_| {
                std::thread::Builder::new()
                    .name("plcd-native".into())
                    .stack_size(COMPILE_STACK)
                    .spawn_scoped(scope, work)
                    .ok()
            })
            .collect();
        // This thread works too; without helpers (none could start) it does all of it.
        work();
        for helper in helpers {
            // A helper that panicked left its function's result empty: reported below.
            let _ = helper.join();
        }
    });
    results
        .into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .into_iter()
        .map(|result| result.unwrap_or_else(|| Err("a compiling thread panicked".into())))
        .collect()
}

impl NativeCode for Code {
    fn run(
        &self,
        memory: &mut NativeMemory<'_>,
        il: Option<&mut IlMemory<'_>>,
        regs: &mut NativeRegs,
    ) -> NativeExit {
        // The fixed operands of the code, and the arrays at fixed places, are checked against
        // these sizes once, here.
        if memory.vars_len() < self.vars_need || memory.words_len() < self.words_need {
            return NativeExit::Interpret;
        }
        match &self.il_needs {
            // Structured Text code reads no instruction-list state: the memory's `il` stays
            // the null `NativeMemory::new` put there, and nothing is built for it.
            None => self.enter(memory, regs),
            Some(needs) => self.run_il(memory, il, regs, needs),
        }
    }

    fn interpret_span(&self, pc: u32) -> u32 {
        self.shape.span(pc).max(1)
    }
}

impl std::fmt::Debug for Code {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Code")
            .field("program", &self.name)
            .field("blocks", &self.shape.blocks())
            .finish()
    }
}

impl Drop for Code {
    fn drop(&mut self) {
        if let Some(module) = self.module.take() {
            // SAFETY: the only pointer into the module's memory is `entry`, which is called
            // only through `&self`; `drop` has `&mut self`, so no call is under way, and `self`
            // is never used after.
            unsafe { module.free_memory() };
        }
    }
}
