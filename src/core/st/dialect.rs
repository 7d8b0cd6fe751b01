//! The forms plcd accepts beyond IEC 61131-3: habits of CODESYS and TwinCAT that the standard
//! gives no other meaning, so that code written for them compiles as it is (docs/ST.md,
//! "CODESYS and TwinCAT habits").
//!
//! The parser and the checker note each use of one as a [`Habit`] at its place and go on as
//! CODESYS would. With `[st] strict = true` every noted habit is an error whose message names
//! the standard's way; without it they cost nothing.

use crate::st::ast::Span;

/// How the project's Structured Text is read: `[st] strict`, `[iec]`'s layout of the direct
/// addresses, `[st] heap_bytes` and `[st] variable_memory_bytes`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dialect {
    /// Refuse every [`Habit`] (IEC 61131-3 only). Default `false`: accept them.
    pub strict: bool,
    /// What `%IX0.0`, `%QW3`, `%MD10` name (`[iec]`); default OpenPLC's numbering.
    pub iec: crate::device::iec::IecLayout,
    /// The bytes of the heap `__NEW` takes its memory from (`[st] heap_bytes`,
    /// compile/heap.rs); 0: no heap, `__NEW` is an error.
    pub heap_bytes: u32,
    /// The system libraries compiled with the project (`[st] system_libraries`).
    pub libraries: crate::st::libraries::SystemLibraries,
    /// The most variable memory the project may take in all, and so one array or one instance
    /// (`[st] variable_memory_bytes`).
    pub variable_memory_bytes: u32,
}

/// `[st] heap_bytes` when the config does not say: 64 KiB.
pub const DEFAULT_HEAP_BYTES: u32 = crate::config::DEFAULT_HEAP_BYTES;

impl Default for Dialect {
    fn default() -> Dialect {
        Dialect {
            strict: false,
            iec: Default::default(),
            heap_bytes: DEFAULT_HEAP_BYTES,
            libraries: Default::default(),
            variable_memory_bytes: crate::config::DEFAULT_VARIABLE_MEMORY_BYTES,
        }
    }
}

/// One non-standard form, as written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Habit {
    /// No `;` after a statement that ends with `END_IF`, `END_CASE`, `END_FOR`, `END_WHILE` or
    /// `END_REPEAT` (the keyword).
    NoSemicolonAfterEnd(&'static str),
    /// No `;` after a type's declaration (`END_STRUCT`, an enumeration's `)`, an alias) before
    /// `END_TYPE` or the next type.
    NoSemicolonAfterType,
    /// `VAR_STAT`: one copy for every instance and every call of the POU.
    VarStat,
    /// `VAR_INST`: a variable kept in the function block's instance.
    VarInst,
    /// Conditional compilation (CODESYS, TwinCAT; `syntax::cond`): noted at each `{define x}`,
    /// `{undefine x}` and `{IF defined (x)}` (its `{ELSIF}`, `{ELSE}` and `{END_IF}` go with it).
    ConditionalPragma,
    /// `PERSISTENT` on a variable block (`VAR PERSISTENT`, `VAR_GLOBAL RETAIN PERSISTENT`,
    /// TwinCAT and CODESYS): retained, and kept by a cold reset too.
    Persistent,
    /// A `;` alone in a variable block (`a : LREAL := 630.0;;`): an empty declaration.
    EmptyDeclaration,
    /// An argument without a value, as TwinCAT's input assistant writes them: `ET => ` binds
    /// nothing (`output`), `IN := ` is the input left out.
    EmptyArgument { output: bool },
    /// A `,` after a call's last argument (`fb(IN := x, Q => q, );`, as TwinCAT projects
    /// write it): nothing after it.
    TrailingComma,
    /// `VAR_INPUT CONSTANT`: an input the POU's body may not write.
    ConstantInput,
    /// An FB instance's internal variable read from outside.
    ReadFbInternal,
    /// An FB instance's VAR_IN_OUT named from outside its body (`inst.io`, matiec): the
    /// variable it is bound to; `inst.io := v` binds it (`compile::inout`).
    InOutThroughInstance,
    /// An FB call that leaves out a VAR_IN_OUT (matiec): the binding of an earlier call or of
    /// `inst.io := v` holds.
    InOutOmitted,
    /// `+ - * / MOD` on `BYTE` … `LWORD`, with each other and with integers.
    BitArithmetic,
    /// A bit string with a `REAL` or `LREAL` in `+ - * /`.
    BitWithReal,
    /// `SHL SHR ROL ROR` on an integer type, on the bit pattern of its width.
    IntegerShift,
    /// A bit string as the count of `SHL SHR ROL ROR` (`SHR(w, n)` with a `BYTE` n).
    BitShiftCount,
    /// `EXPT` of an integer base, raised in the real type wanted (`LREAL` without one).
    IntegerExpt,
    /// `TIME()`: the PLC's clock as a `TIME`.
    TimeClock,
    /// A duration literal beyond the signed 64-bit nanoseconds of plcd's `TIME`/`LTIME`, up to
    /// CODESYS's and TwinCAT's unsigned `LTIME` maximum (`LTIME#213503d23h34m33s709ms551us615ns`,
    /// 2^64 − 1 ns): its 64 bits, as those runtimes hold it.
    UnsignedLtime,
    /// `SIZEOF(x)`: the bytes a variable or a type takes.
    Sizeof,
    /// `__NEW(T, n)` or `__DELETE(p)` (TwinCAT, CODESYS): dynamic memory (compile/heap.rs);
    /// the operator's name.
    DynamicMemory(&'static str),
    /// A VAR_INPUT of a generic type (`x : ANY_INT`) in a user POU (`compile::generic`).
    GenericInput,
    /// `BIT`: a STRUCT member or FUNCTION_BLOCK variable, a `BOOL` in plcd (`compile::bit`).
    Bit,
    /// A call's positional arguments followed by named ones (`F(x, 2, DEC := ',')`, TwinCAT).
    PositionalThenNamed,
    /// A standard string function's input named as CODESYS names it (`LEN(STR := s)`): the
    /// CODESYS name, and the standard's.
    CodesysParameter(&'static str, &'static str),
    /// The BCD conversions of CODESYS's Util library (`BCD_TO_INT`, `INT_TO_BCD`…).
    UtilBcd,
    /// A bit string given where an integer is wanted, or an integer where a bit string is,
    /// converted implicitly where no value is lost (`i := b` with a BYTE b and an INT i).
    ImplicitConversion,
    /// An integer or bit string given where another one is wanted that does not hold every
    /// value of it (`u := i` with an INT i and a UINT u, `i := d` with a DINT d): converted as
    /// the explicit conversion does, wrapping, with a warning (`compile::implicit`). The two
    /// types' names.
    LossyConversion { from: &'static str, to: &'static str },
    /// An enumeration's value where an integer is wanted (`i := eState`): its number.
    EnumToInteger,
    /// A `DATE` plus or minus a `TIME` (`dat + t#1d`, OSCAT): the day of the instant
    /// (`compile::calendar`).
    DateArithmetic,
    /// An integer where CODESYS's type class is wanted (`ExpectedTypeClass :=
    /// UDINT_TO_INT(Expected.TypeClass)`, TcUnit): its number (`compile::type_class_int`).
    IntegerToTypeClass,
    /// A function block instance passed as `VAR_IN_OUT CONSTANT` called (`CpuCounter();`,
    /// TcUnit): the call writes the caller's instance (`compile::constant_instance`).
    ConstantInstanceCalled,
    /// A FUNCTION_BLOCK's variable of a declared type (an interface) initialised with an
    /// instance the block declares before (`Logger : I_Logger := fbLogger;`, TcUnit): set at
    /// the start of the block's `FB_init` (`compile::instance_init`).
    InstanceInitialValue,
    /// A FUNCTION's or method's `VAR`, or a `VAR_TEMP`, initialised from the call's or the
    /// instance's variables (`pTest : I_Element := pList[Index];`, compile/local_init.rs).
    VariableInitialValue,
    /// The FOR variable written in the loop's body: the loop goes on from the value written
    /// (`compile::for_written`).
    ForVariableWritten,
    /// A FOR loop counting in an array element or a struct member (`FOR a[1] := …`,
    /// `FOR s.n := …`, TwinCAT): its indices constant, so the place is fixed for the loop.
    ForElement,
    /// An assignment inside an expression (`a := b := FALSE`, `IF (i := i + 1) >= 3`,
    /// CODESYS): its value is the value assigned (`compile::assign_expr`).
    AssignExpr,
    /// An integer literal too large for the other operand's type, which widens the operation
    /// (`i * 60000` with an INT `i` is computed in DINT).
    WidenedLiteral,
    /// A `POINTER TO` used as a 64-bit number (`ULINT`, `LWORD`), or such a number as a
    /// pointer.
    PointerInteger,
    /// `p[i]` on a `POINTER TO T`: the `T` `i` elements after the one `p` points to.
    PointerIndex,
    /// `AND`, `OR`, `XOR` on integers: on their two's complement bits.
    BitwiseInteger,
    /// `AND_THEN`, `OR_ELSE` (the operator as written): the right operand evaluated only when
    /// the left does not decide.
    ShortCircuit(&'static str),
    /// `UNION … END_UNION`: members sharing their bytes.
    Union,
    /// `JMP label;` or `label:` in ST (IEC 61131-3 has them in IL only).
    Jump,
    /// An enumeration's base type after its values, `(A, B) BYTE`.
    EnumBaseAfterValues,
    /// `E.Value`: a value of the enumeration `E` named with a dot.
    EnumDotValue,
    /// A CASE's `ELSE` after labels covering every value of its enumeration selector.
    CoveredCaseElse,
    /// `.x`, CODESYS's global scope operator: the global `x`, even where a variable of the
    /// scope is also called `x`.
    GlobalScope,
    /// `VAR_GENERIC CONSTANT` and an instance's type with arguments, `FB_Log<20>` (TwinCAT
    /// 3.1.4026 generic constants, `compile::generic_constants`).
    GenericConstants,
    /// A variable named as its FUNCTION or METHOD, which has no result type (`Test : REFERENCE
    /// TO FB_Test;` in TcUnit's `FUNCTION TEST`): the name is the variable in the body.
    VariableNamedAsFunction,
    /// `fbA := fbB;`: a function block instance assigned, its whole memory copied, as CODESYS
    /// and TwinCAT do (`compile::fb_value`).
    InstanceAssignment,
    /// A FUNCTION or METHOD whose result is a function block instance, a copy the caller
    /// assigns or uses (`METHOD GetTestByPosition : FB_Test`, TcUnit; `compile::fb_value`).
    InstanceResult,
    /// A FUNCTION's `VAR` holding a function block instance: a fresh one at each call
    /// (`compile::fb_value`).
    InstanceInFunction,
}

impl Habit {
    /// The error `[st] strict` reports: what is not standard, and the standard's way.
    pub fn strict_message(self) -> String {
        match self {
            Habit::NoSemicolonAfterEnd(end) => {
                format!("`;` expected after `{end}` (IEC 61131-3 ends every statement with `;`; `[st] strict` is on)")
            }
            Habit::NoSemicolonAfterType => "`;` expected after the type's declaration (IEC 61131-3 ends every type declaration with `;`; `[st] strict` is on)".to_string(),
            Habit::VarStat => "`VAR_STAT` is not IEC 61131-3: declare the variable in `VAR` of a PROGRAM, or as a VAR_GLOBAL (`[st] strict` is on)".to_string(),
            Habit::VarInst => "`VAR_INST` is not IEC 61131-3: declare the variable in the function block's `VAR` (`[st] strict` is on)".to_string(),
            Habit::ConditionalPragma => "conditional compilation (`{IF defined (x)}`, `{define x}`) is CODESYS's and TwinCAT's: IEC 61131-3 gives a pragma no meaning; keep the variant wanted (`[st] strict` is on)".to_string(),
            Habit::Persistent => "`PERSISTENT` is TwinCAT's and CODESYS's: IEC 61131-3 writes `RETAIN` (`[st] strict` is on)".to_string(),
            Habit::EmptyDeclaration => "an empty declaration (a `;` alone) is not IEC 61131-3: remove the `;` (`[st] strict` is on)".to_string(),
            Habit::EmptyArgument { output: true } => "`=>` without a variable is not IEC 61131-3: leave out the outputs the call does not read (`[st] strict` is on)".to_string(),
            Habit::EmptyArgument { output: false } => "`:=` without a value is not IEC 61131-3: leave out the inputs the call does not give (`[st] strict` is on)".to_string(),
            Habit::TrailingComma => "a `,` after the last argument is not IEC 61131-3: remove it (`[st] strict` is on)".to_string(),
            Habit::ConstantInput => "`VAR_INPUT CONSTANT` is not IEC 61131-3: write `VAR_INPUT` (`[st] strict` is on)".to_string(),
            Habit::ReadFbInternal => "IEC 61131-3 reads only an instance's inputs and outputs from outside: pass the value out through a VAR_OUTPUT (`[st] strict` is on)".to_string(),
            Habit::InOutThroughInstance => "IEC 61131-3 names a VAR_IN_OUT only inside its function block's body: use the variable the call binds to it (`[st] strict` is on)".to_string(),
            Habit::InOutOmitted => "IEC 61131-3 binds every VAR_IN_OUT at each call of a function block: give it again (`[st] strict` is on)".to_string(),
            Habit::BitArithmetic => "IEC 61131-3 has no arithmetic on bit strings: convert to an integer first, `WORD_TO_UINT(w) + 1` (`[st] strict` is on)".to_string(),
            Habit::BitWithReal => "IEC 61131-3 has no arithmetic between a bit string and a real: convert first, `BYTE_TO_REAL(b) * r` (`[st] strict` is on)".to_string(),
            Habit::IntegerShift => "IEC 61131-3 shifts bit strings only: `WORD_TO_INT(SHR(INT_TO_WORD(i), n))` (`[st] strict` is on)".to_string(),
            Habit::BitShiftCount => "IEC 61131-3 counts a shift with an integer: `SHR(w, BYTE_TO_USINT(n))` (`[st] strict` is on)".to_string(),
            Habit::IntegerExpt => "IEC 61131-3 raises a `REAL` or `LREAL` base only: `EXPT(INT_TO_REAL(i), n)` (`[st] strict` is on)".to_string(),
            Habit::TimeClock => "`TIME()` is CODESYS's clock, not IEC 61131-3: measure durations with the standard timers (`TON`) (`[st] strict` is on)".to_string(),
            Habit::UnsignedLtime => "the duration is beyond `LTIME`'s signed 64-bit nanoseconds (IEC 61131-3; CODESYS's and TwinCAT's unsigned `LTIME` goes to `LTIME#213503d23h34m33s709ms551us615ns`; `[st] strict` is on)".to_string(),
            Habit::Sizeof => "`SIZEOF` is not IEC 61131-3 (`[st] strict` is on)".to_string(),
            Habit::DynamicMemory(op) => format!("`{op}` is TwinCAT's and CODESYS's dynamic memory; IEC 61131-3 has none: declare the instances, an array of them for a list (`[st] strict` is on)"),
            Habit::Bit => "`BIT` is CODESYS and TwinCAT, not IEC 61131-3: declare a `BOOL` (`[st] strict` is on)".to_string(),
            Habit::GenericInput => "a VAR_INPUT of a generic type (`ANY…`) is CODESYS: IEC 61131-3 keeps generic types to its standard functions; write one POU per type (`[st] strict` is on)".to_string(),
            Habit::ImplicitConversion => "IEC 61131-3 converts between bit strings and integers only explicitly: `BYTE_TO_INT(b)` (`[st] strict` is on)".to_string(),
            Habit::LossyConversion { from, to } => format!("IEC 61131-3 converts `{from}` to `{to}` only explicitly, as the value may change: `{from}_TO_{to}(…)` (`[st] strict` is on)"),
            Habit::DateArithmetic => "IEC 61131-3 adds a `TIME` to a `TOD` or a `DT`, not to a `DATE`: go through a `DT`, `DT_TO_DATE(ADD_DT_TIME(DATE_TO_DT(d), t))` (SUB_DT_TIME to subtract) (`[st] strict` is on)".to_string(),
            Habit::EnumToInteger => "IEC 61131-3 gives an enumeration's value no number to convert to: test the value, `CASE e OF E#A: i := 0; …` (`[st] strict` is on)".to_string(),
            Habit::IntegerToTypeClass => "IEC 61131-3 converts no integer to an enumeration: give one of `__SYSTEM.TYPE_CLASS`'s values (`[st] strict` is on)".to_string(),
            Habit::InstanceInitialValue => "an initial value is a constant expression in IEC 61131-3, and an instance's place is none: assign the instance in the block's code or in FB_init (`[st] strict` is on)".to_string(),
            Habit::VariableInitialValue => "an initial value is a constant expression in IEC 61131-3: assign the variable at the start of the body (`[st] strict` is on)".to_string(),
            Habit::ConstantInstanceCalled => "IEC 61131-3 calls no CONSTANT function block instance, as a call writes it: pass it as a plain VAR_IN_OUT (`[st] strict` is on)".to_string(),
            Habit::ForVariableWritten => "IEC 61131-3 forbids writing the FOR variable in the loop: count with a WHILE loop and a variable of its own (`[st] strict` is on)".to_string(),
            Habit::ForElement => "IEC 61131-3 counts in a variable named alone, not in an element or a member: count in a local variable and copy it (`[st] strict` is on)".to_string(),
            Habit::AssignExpr => "IEC 61131-3 assigns in a statement only, not inside an expression: assign first, then use the variable, `b := FALSE; a := b;` (`[st] strict` is on)".to_string(),
            Habit::WidenedLiteral => "the constant does not fit the other operand's type: IEC 61131-3 widens only explicitly, `INT_TO_DINT(i) * 60000` (`[st] strict` is on)".to_string(),
            Habit::PointerInteger => "IEC 61131-3 has no conversion between references and numbers: move a `POINTER TO` by `p + n` and compare pointers with each other (`[st] strict` is on)".to_string(),
            Habit::PointerIndex => "indexing a `POINTER TO` is CODESYS, not IEC 61131-3: move the pointer by bytes and dereference it, `(p + i * 2)^` for an INT (`[st] strict` is on)".to_string(),
            Habit::BitwiseInteger => "IEC 61131-3 has `AND`, `OR` and `XOR` on BOOL and bit strings only: `INT_TO_WORD(i) AND 16#FF` (`[st] strict` is on)".to_string(),
            Habit::ShortCircuit(op) => format!("`{op}` is CODESYS, not IEC 61131-3, whose `AND` and `OR` evaluate both operands: nest the test, `IF p <> 0 THEN IF p^ > 0 THEN …` (`[st] strict` is on)"),
            Habit::Union => "`UNION` is CODESYS, not IEC 61131-3, which has no type whose members share their bytes: declare a STRUCT (`[st] strict` is on)".to_string(),
            Habit::Jump => "`JMP` and labels are CODESYS in ST: IEC 61131-3 has them in IL only; write IF, WHILE, REPEAT or EXIT (`[st] strict` is on)".to_string(),
            Habit::EnumBaseAfterValues => "IEC 61131-3 writes an enumeration's base type before its values: `BYTE (A, B)` (`[st] strict` is on)".to_string(),
            Habit::EnumDotValue => "IEC 61131-3 names an enumeration's value with `#`: `E#Value` (`[st] strict` is on)".to_string(),
            Habit::GlobalScope => "`.x`, the global scope operator, is CODESYS, not IEC 61131-3: name the global plainly, and rename the variable that hides it (`[st] strict` is on)".to_string(),
            Habit::GenericConstants => "generic constants (`VAR_GENERIC CONSTANT`, `FB_Log<20>`) are TwinCAT 3.1.4026, not IEC 61131-3: declare one function block per size, or a constant the block's variables are sized by (`[st] strict` is on)".to_string(),
            Habit::InstanceAssignment => "IEC 61131-3 assigns no function block instance: copy the variables wanted one by one, or pass the instance as a VAR_IN_OUT (`[st] strict` is on)".to_string(),
            Habit::InstanceResult => "a FUNCTION's result is a value of a data type in IEC 61131-3, not a function block instance: return a STRUCT, or pass the instance as a VAR_IN_OUT (`[st] strict` is on)".to_string(),
            Habit::InstanceInFunction => "IEC 61131-3 declares no function block instance in a FUNCTION, which keeps no state: declare a FUNCTION_BLOCK, or pass the instance as a VAR_IN_OUT (`[st] strict` is on)".to_string(),
            Habit::CoveredCaseElse => "unreachable `ELSE`: the labels cover every value of the selector's type; remove the `ELSE` (`[st] strict` is on)".to_string(),
            Habit::PositionalThenNamed => "IEC 61131-3 gives a call's arguments all by position or all by name: name each one (`[st] strict` is on)".to_string(),
            Habit::CodesysParameter(codesys, iec) => format!("`{codesys}` is CODESYS's name of this input: IEC 61131-3 names it `{iec}` (`[st] strict` is on)"),
            Habit::VariableNamedAsFunction => "IEC 61131-3 gives a FUNCTION's name to its result, and a variable of the same name makes the POU's name ambiguous: rename the variable (`[st] strict` is on)".to_string(),
            Habit::UtilBcd => "this BCD conversion is CODESYS's Util library: IEC 61131-3 writes `BYTE_BCD_TO_USINT`, `USINT_TO_BCD_BYTE` and the like (`[st] strict` is on)".to_string(),
        }
    }
}

/// A habit noted at a place of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Noted {
    pub span: Span,
    pub habit: Habit,
}
