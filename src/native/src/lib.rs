//! plcd-native: machine code for Structured Text and instruction-list programs.
//!
//! The VM interprets a program's ops one at a time; this crate compiles the same ops into
//! machine code for the processor plcd runs on, with Cranelift, and attaches it to the
//! [`Program`] so that [`Vm::run`](plcd_core::vm::Vm::run) runs it in place of the interpreter
//! wherever it can. The contract between them is `plcd_core::lang::native`: native code is
//! the interpreter's behaviour to the step — the same step count, the same stops, the same
//! memory — and hands back to the interpreter whatever it cannot do exactly, so a program
//! behaves the same with it or without it, only faster.
//!
//! The layers, bottom up:
//! - `analysis`: what a Structured Text program's ops need (the static depth of the
//!   evaluation stack at each instruction, the entry points, the blocks), and whether the
//!   program can be compiled;
//! - `blocks`: blocks and the interpreter's share from a program's leaders, for both;
//! - `carry`: which values of variables a Structured Text body's blocks receive in
//!   registers from the blocks before them, and what a call may change;
//! - `inline`: which calls of a Structured Text body are compiled inline (small bodies that
//!   call nothing), decided before its code is generated;
//! - `codegen`: Structured Text's ops as Cranelift IR;
//! - `il`: the instruction list's analysis and code generator (its ops have no evaluation
//!   stack: rungs of bit logic and data, which it compiles, and the rest, which it leaves to
//!   the interpreter);
//! - `code`: the one module with `unsafe`: executable memory and the call into it.

#![deny(unsafe_code)]

mod analysis;
mod blocks;
mod carry;
mod code;
mod codegen;
mod helpers;
mod il;
mod inline;

use std::sync::Arc;

use plcd_core::lang::native::NativeCode;
use plcd_core::lang::{Language, Program};
use plcd_core::project::Project;

/// Instructions of an instruction-list program compiled to native code, at most: the rest
/// of a longer program runs on the interpreter, so that a load takes bounded time.
pub const IL_MAX_COMPILED: usize = il::MAX_COMPILED;

/// Why a program has no native code (it runs on the interpreter).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Error {
    /// The program's code has a shape native code does not take (an evaluation stack whose
    /// depth differs between two paths to one instruction, a `RETURN` with values on the
    /// stack): the interpreter runs it as it is.
    #[error("program \"{program}\": {reason}")]
    Unsupported { program: String, reason: String },
    /// An instruction-list program with so many instructions native code leaves to the
    /// interpreter (timers, counters, edges, calls, …, or all past the first
    /// [`IL_MAX_COMPILED`] of a long program) that native code would not be faster: it runs
    /// on the interpreter, as intended ([`attach`] does not report it).
    #[error(
        "program \"{program}\": {interpreted} of its {instructions} instructions are the \
         interpreter's: native code would be slower"
    )]
    Slower { program: String, interpreted: usize, instructions: usize },
    /// Cranelift has no code generator for this processor.
    #[error("no code generator for this processor: {0}")]
    Host(String),
    /// Cranelift refused the generated function (a bug of this crate).
    #[error("program \"{program}\": code generation failed: {message}")]
    Codegen { program: String, message: String },
    /// The system refused executable memory (under systemd, `MemoryDenyWriteExecute=yes`).
    #[error("program \"{program}\": no executable memory: {message}")]
    Memory { program: String, message: String },
}

/// Compiles `program` to native code.
pub fn compile(program: &Program) -> Result<Arc<dyn NativeCode>, Error> {
    compile_as(program, false)
}

/// Compiles `program` to native code even where it would be slower than the interpreter
/// ([`Error::Slower`]): for the tests and benches that compare the two on any program.
pub fn compile_even_if_slower(program: &Program) -> Result<Arc<dyn NativeCode>, Error> {
    compile_as(program, true)
}

/// [`compile_even_if_slower`] with `bytes` of machine stack for the code's calls instead of
/// the 64 KiB every program has: for the tests of the calls the interpreter makes when native
/// code's machine stack is spent.
#[doc(hidden)]
pub fn compile_with_stack(program: &Program, bytes: u64) -> Result<Arc<dyn NativeCode>, Error> {
    compile_with(program, true, bytes)
}

fn compile_as(program: &Program, even_if_slower: bool) -> Result<Arc<dyn NativeCode>, Error> {
    compile_with(program, even_if_slower, code::NATIVE_STACK)
}

fn compile_with(
    program: &Program,
    even_if_slower: bool,
    stack: u64,
) -> Result<Arc<dyn NativeCode>, Error> {
    let shape = match program.language {
        Language::StructuredText => code::Shape::StructuredText(
            analysis::analyse(program)
                .map_err(|reason| Error::Unsupported { program: program.name.clone(), reason })?,
        ),
        Language::InstructionList => {
            let analysis = il::analyse(&program.code);
            if !analysis.worth_compiling() && !even_if_slower {
                return Err(Error::Slower {
                    program: program.name.clone(),
                    interpreted: analysis.interpreted(),
                    instructions: analysis.instructions,
                });
            }
            code::Shape::InstructionList(analysis)
        }
    };
    // Cranelift reports most failures as errors, a few (the instruction-cache flush of the
    // new code on some processors) as panics; either leaves this program to the interpreter.
    // The program is only read, so a panic leaves nothing half changed.
    let compiled = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        code::Code::compile(program, shape, stack)
    }));
    match compiled {
        Ok(result) => Ok(Arc::new(result?)),
        Err(panic) => {
            Err(Error::Memory { program: program.name.clone(), message: panic_text(&*panic) })
        }
    }
}

/// Compiles every program of `project` to native code and attaches it (but the
/// instruction-list programs it would make slower, [`Error::Slower`]); the
/// programs it could not compile keep running on the interpreter, and their errors are
/// returned for the caller to report. The compiling is done on a thread of its own, with the
/// stack Cranelift needs, which ends before this returns.
pub fn attach(project: &mut Project) -> Vec<Error> {
    let programs: Vec<&mut Program> = project.programs.iter_mut().collect();
    if programs.is_empty() {
        return Vec::new();
    }
    std::thread::scope(|scope| {
        let compiler = std::thread::Builder::new()
            .name("plcd-native".into())
            .stack_size(code::COMPILE_STACK)
            .spawn_scoped(scope, move || {
                let mut errors = Vec::new();
                for program in programs {
                    match compile(program) {
                        Ok(native) => program.native = Some(native),
                        Err(Error::Slower { .. }) => {}
                        Err(e) => errors.push(e),
                    }
                }
                errors
            });
        match compiler {
            Ok(thread) => thread.join().unwrap_or_else(|panic| {
                vec![Error::Host(format!("the compiler thread panicked: {}", panic_text(&*panic)))]
            }),
            Err(e) => vec![Error::Host(format!("no thread to compile on: {e}"))],
        }
    })
}

fn panic_text(panic: &(dyn std::any::Any + Send)) -> String {
    if let Some(text) = panic.downcast_ref::<&str>() {
        text.to_string()
    } else if let Some(text) = panic.downcast_ref::<String>() {
        text.clone()
    } else {
        "the code generator panicked".into()
    }
}
