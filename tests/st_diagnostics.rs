//! Every error message of the Structured Text compiler has a golden case.
//!
//! The compiler (`src/core/st/compile/`) reports its errors with `format!` texts. Each text,
//! with every `{…}` written `{}`, is a *template*; [`MESSAGES`] names, for each template, a case
//! `tests/golden/st/<case>/` whose `expected.stderr` shows it (`tests/golden_diagnostics.rs` runs
//! the cases through the real `plcd check`). The tests here keep the three in step:
//!
//! - every row's case exists and reports a message of its template;
//! - every string literal of the compiler sources that holds a space (outside `#[cfg(test)]`
//!   and the texts of `expect`, `unreachable!` and `panic!`) is a template of [`MESSAGES`], of
//!   [`UNREACHABLE`], or a part messages are built from ([`PARTS`]); every entry of the three
//!   is such a literal, so a reworded message cannot leave a stale row behind;
//! - every case under `tests/golden/st/` is the case of some row.
//!
//! To add a message: write the minimal project that reports it and nothing else in
//! `tests/golden/st/<kebab-name>/` (`plcd.toml` with `[[program]] file = "main.st"`, and
//! `main.st`), run `PLCD_BLESS=1 cargo test --test golden_diagnostics`, read the new
//! `expected.stderr` (the message, at the right `line:col`), and add the row
//! `("<template>", "<kebab-name>")` to [`MESSAGES`]. A literal that is only a part of messages
//! (a word given to a shared helper, a hint appended to a message) goes to [`PARTS`]; a message
//! no program can reach goes to [`UNREACHABLE`] with the reason.

mod harness;

use std::fs;
use std::path::Path;

use harness::golden::matches_template;

const CASES: &str = "tests/golden/st";
const SOURCES: &str = "src/core/st/compile";

/// Each message template of the compiler and a golden case that reports it. A template may
/// have several rows (one per case that shows it).
const MESSAGES: &[(&str, &str)] = &[
    // heap.rs: __NEW and __DELETE
    (
        "`{}` takes memory from the heap, and `[st] heap_bytes` is {}: give it the bytes the program allocates at most (docs/ST.md, Dynamic memory)",
        "heap-none",
    ),
    (
        "`__NEW` stands in a POU's statements, not in an initial value: assign it at the first scan, `IF p = 0 THEN p := __NEW(T); END_IF`",
        "heap-new-initial-value",
    ),
    (
        "`__DELETE(p)` frees a block and gives no value: write it as a statement of its own, `__DELETE(p);` (TwinCAT, CODESYS)",
        "heap-delete-in-expression",
    ),
    // decl.rs: declarations, types, initial values, locations
    ("`{}`: names starting with `__` are reserved", "reserved-name"),
    ("`{}` is an elementary type", "elementary-type-name"),
    ("`{}` is already declared ({})", "already-declared"),
    ("an integer constant is needed here, not `{}`", "integer-constant-needed"),
    ("a constant expression is needed here", "constant-expression-needed"),
    ("`{}` is not a type", "not-a-type"),
    ("`{}` contains an instance of itself", "fb-contains-itself"),
    ("unknown type `{}`{}", "unknown-type"),
    ("a STRING's length must be 1..255, not {}", "string-length"),
    ("a WSTRING's length must be 1..255, not {}", "wstring-length"),
    ("a `{}` literal is one character", "char-literal-length"),
    ("empty or too large array range `{}..{}`", "empty-array-range"),
    ("a subrange needs an integer type, not `{}`", "subrange-base"),
    ("`{}..{}` is not a subrange of `{}`", "subrange-bounds"),
    ("an enumeration's base must be an integer type, not `{}`", "enum-base-not-integer"),
    (
        "an enumeration's values are names (`INT (A, B := 5)`); arguments that are not names go to a function block's FB_init only (`fb : T(5, 'A')`)",
        "enum-arguments",
    ),
    ("`{}` is already a value of this enumeration", "duplicate-enum-value"),
    ("constant `{}` does not fit `{}`", "constant-does-not-fit"),
    ("`{}` has no value `{}`", "enum-init-no-value"),
    ("type `{}` is defined in terms of itself", "self-referential-type"),
    (
        "a STRUCT member's address is partly specified (`AT %I*`, `%Q*`, `%M*`): VAR_CONFIG or [iec.variables] binds it for each variable",
        "located-struct-member",
    ),
    (
        "`{}.{}` is bound to a device (VAR_CONFIG, [iec.variables]): give its initial value in its binding or in the declaration of `{}`",
        "struct-member-on-device-initializer",
    ),
    (
        "`{}` has its member `{}` at a partly specified address: a {} cannot be of it (IEC 61131-3): declare the variable in VAR or VAR_OUTPUT",
        "struct-partly-located-input",
    ),
    ("`{}` is already declared in this STRUCT", "duplicate-struct-member"),
    // implicit.rs: CODESYS's implicit conversions that may change a value (a warning)
    (
        "`{}` converted implicitly to `{}`: the value wraps to {} bits ({} becomes {}); write `{}_TO_{}(…)` to say so",
        "warning-lossy-conversion",
    ),
    (
        "`{}` converted implicitly to `{}`: the value is rounded to the nearest `{}` ({} becomes {}); write `{}_TO_{}(…)` to say so",
        "warning-lossy-real-conversion",
    ),
    (
        "`{}` converted implicitly to `{}`: the value is rounded to the nearest `{}` ({} becomes {}); write `{}_TO_{}(…)` to say so",
        "warning-lossy-integer-to-real",
    ),
    // varlen.rs: ARRAY [*] and LOWER_BOUND / UPPER_BOUND
    (
        "`ARRAY [*]` is only the type of a VAR_IN_OUT of a FUNCTION, FUNCTION_BLOCK or METHOD",
        "open-array-misplaced",
    ),
    (
        "an `ARRAY [*]` is used element by element or passed on to a VAR_IN_OUT, not copied whole",
        "open-array-whole",
    ),
    ("`{}` needs an array, not `{}`", "bound-needs-array"),
    ("the dimension of `{}` must be a constant from 1 to {}", "bound-dimension"),
    ("VAR_IN_OUT `{}` of `{}` needs a `{}` variable, not `{}`", "open-array-argument"),
    (
        "an array located at a device cannot be passed to an `ARRAY [*]`: copy it into a variable first",
        "open-array-at-device",
    ),
    // generic.rs: CODESYS's generic inputs (`x : ANY_INT`)
    (
        "`{}` is only the type of a VAR_INPUT of a FUNCTION, FUNCTION_BLOCK or METHOD",
        "generic-misplaced",
    ),
    (
        "`{}` of `{}` is `{}`: it needs a variable of that category, not {}",
        "generic-argument",
    ),
    (
        "`{}` of `{}` is `{}`: it needs a variable of that category, not {}",
        "generic-argument-value",
    ),
    ("`{}` has no value `{}`", "type-class-value"),
    // bit.rs: TwinCAT's and CODESYS's BIT
    (
        "`BIT` is only the type of a STRUCT or UNION member or of a FUNCTION_BLOCK's VAR, VAR_INPUT or VAR_OUTPUT",
        "bit-misplaced",
    ),
    // union.rs: CODESYS's UNION
    ("a UNION member cannot be located", "located-union-member"),
    ("a UNION member cannot be {}: other members' bytes would forge it", "union-member-instance"),
    ("`{}` is already declared in this UNION", "duplicate-union-member"),
    (
        "only one member of a UNION can have an initial value, and `{}` has one",
        "union-two-initial-values",
    ),
    ("a UNION's initial value gives one member only", "union-initial-two-members"),
    (
        "`{}` holds a string whose terminating zero `{}` overlaps: a string inside an array or STRUCT member of a UNION must end past every other member",
        "union-string-end",
    ),
    (
        "a string member of a UNION that another member overlaps cannot be passed to a VAR_IN_OUT: other members' bytes may leave it without its terminating zero; pass a copy",
        "union-string-in-out",
    ),
    // jumps.rs: JMP and labels
    ("label `{}` is already declared at line {}", "jump-duplicate-label"),
    ("no label `{}` in this body{}", "jump-unknown-label"),
    (
        "`JMP {}` goes into the {} at line {}: a jump goes to a label of its own statement list or of one around it",
        "jump-into-block",
    ),
    // short_circuit.rs: AND_THEN, OR_ELSE
    ("`{}` needs `BOOL` operands, not `{}`", "short-circuit-not-bool"),
    ("too many initial values for `{}` ({} elements)", "too-many-initial-values"),
    ("`{}` has no member `{}`{}", "no-member"),
    ("`{}` has no variable `{}` to initialize", "fb-init-no-variable"),
    ("`{}` is `{}`: its initial value must be written `[…]` or `(…)`", "init-needs-brackets"),
    ("this initial value does not fit `{}`", "init-does-not-fit"),
    ("the initial value of `{}` must be a constant expression", "init-not-constant"),
    ("`{}` is already declared (line {})", "already-declared"),
    ("`{}` is a standard function: the name is reserved", "standard-function-name"),
    ("an ACTION outside a POU needs its POU: `ACTION Pou.Name:`", "action-outside-a-pou"),
    ("`{}` is not a PROGRAM or FUNCTION_BLOCK of the project", "action-owner-unknown"),
    ("`{}` is a FUNCTION: only a PROGRAM or a FUNCTION_BLOCK has actions", "action-of-function"),
    ("`{}` is an action: it takes no arguments", "action-with-arguments"),
    // access_paths.rs: VAR_ACCESS
    ("`{}` is a program instance: an access path names one of its variables (`{}.x`)", "access-path-whole-instance"),
    ("`{}` is neither a program instance of the configuration nor a global variable{}", "access-path-unknown-start"),
    (
        "`{}` is a {}: only a PROGRAM or a CONFIGURATION declares access paths (a {}'s variables have no one place clients could name)",
        "access-path-in-function-block",
    ),
    (
        "`{}` is a {}: only a PROGRAM or a CONFIGURATION declares access paths (a {}'s variables have no one place clients could name)",
        "access-path-in-function",
    ),
    (
        "the PROGRAM `{}` has {} instances: its access path `{}` would name a variable of each; declare the access paths in the CONFIGURATION (`{} : {}.{} : …`)",
        "access-path-program-instances",
    ),
    ("`{}` is already declared (line {})", "access-path-declared-twice"),
    ("the access path `{}` has the name of {}: a client's name must mean one thing", "access-path-name-clash"),
    ("`{}` is {} ({}): its access path's type is {}, not `{}`", "access-path-device-type"),
    ("`{}` has no variable `{}`{}", "access-path-unknown-variable"),
    ("`{}` has no member `{}`{}", "access-path-no-member"),
    (
        "`{}` takes no subscript: in an access path, only an array variable does",
        "access-path-subscript-not-variable",
    ),
    ("`{}` is `{}`: it has no variables or members", "access-path-into-elementary"),
    ("`{}` is `{}`, not `{}`", "access-path-type-mismatch"),
    (
        "`{}` is {} of `{}`: an access path names a variable the instance holds from one scan to the next (VAR, VAR_INPUT, VAR_OUTPUT; a global by its own name)",
        "access-path-temp",
    ),
    // var_config.rs: VAR_CONFIG
    ("`{}` is not a PROGRAM instance of {}{}", "config-var-config-not-an-instance"),
    ("`{}` is not a PROGRAM instance of {}{}", "config-iec-variables-not-an-instance"),
    ("VAR_CONFIG names a variable of a program instance: `{}.variable`", "config-var-config-no-variable"),
    ("`{}` has no variable `{}`{}", "config-var-config-unknown-variable"),
    ("`{}` has no variable `{}`{}", "config-iec-variables-unknown-variable"),
    (
        "`{}` is `{}`: {} binds a variable of a program instance or of a FUNCTION_BLOCK instance inside it, or a member of a struct variable of one at any depth, not an element of an array",
        "config-var-config-array-element",
    ),
    (
        "`{}` has {} instances in the project and actions: {} binds a variable of a PROGRAM with actions for its only instance (the actions' code is shared by all)",
        "config-var-config-shared-program-with-actions",
    ),
    (
        "`{}` is not declared at a partly specified address (`AT %I*`, `%Q*`, `%M*`): {} binds only such a variable",
        "config-var-config-not-partly-specified",
    ),
    (
        "`{}` is not declared at a partly specified address (`AT %I*`, `%Q*`, `%M*`): {} binds only such a variable",
        "config-iec-variables-not-partly-specified",
    ),
    ("`%{}` does not fit `{}`, declared at `%{}`", "config-var-config-address-does-not-fit"),
    ("`%{}` does not fit `{}`, declared at `%{}`", "config-iec-variables-does-not-fit"),
    ("`{}` is `{}`, not `{}`", "config-var-config-type"),
    (
        "VAR_CONFIG entry `{}` gives neither an address (`AT %QX0.1`) nor an initial value",
        "config-var-config-nothing-given",
    ),
    ("`{}` is `{}`: it has no variables or members", "config-var-config-no-members"),
    (
        "`{}` has no value of the instance's own: a VAR_TEMP, VAR_IN_OUT, VAR_EXTERNAL or VAR_STAT cannot be given one in VAR_CONFIG",
        "config-var-config-not-the-instances-own",
    ),
    ("`{}` is already bound by {} ({})", "config-var-config-bound-twice"),
    ("`{}` is already bound by {} ({})", "config-iec-variables-bound-by-var-config"),
    ("`{}` is already bound by {} ({})", "config-iec-variables-bound-twice"),
    // fb_value.rs: function block instances as values
    (
        "type mismatch: `{}` cannot be assigned to the instance of `{}`: an instance is assigned an instance of the same function block only",
        "instance-assigned-value",
    ),
    (
        "a method cannot be called on the instance a call returns: assign the result to an instance, then call the method on that",
        "method-on-call-result",
    ),
    (
        "an instance of `{}` cannot be assigned to an instance of `{}`: the copy is between instances of the same function block only (pass a derived instance as a VAR_IN_OUT or an interface instead)",
        "instance-assigned-other-block",
    ),
    // memory_limit.rs: `[st] variable_memory_bytes`
    (
        "{} takes {} bytes of variable memory, more than `[st] variable_memory_bytes` allows ({}): raise it in the config (at most {}) or declare less",
        "array-too-large",
    ),
    (
        "{} takes {} bytes of variable memory, more than `[st] variable_memory_bytes` allows ({}): raise it in the config (at most {}) or declare less",
        "array-too-large-configured",
    ),
    (
        "{} takes {} bytes of variable memory, more than `[st] variable_memory_bytes` allows ({}): raise it in the config (at most {}) or declare less",
        "instance-too-large",
    ),
    (
        "with this declaration, variable memory takes {} bytes in all, more than `[st] variable_memory_bytes` allows ({}): raise it in the config (at most {}) or declare less",
        "variable-memory-total-too-large",
    ),
    // instance_args.rs: a configuration's program instance arguments
    ("a function block instance cannot be assigned", "config-argument-instance"),
    ("`{}` has no VAR_INPUT or VAR_OUTPUT `{}`{}", "config-argument-unknown"),
    (
        "`{}` is not a VAR_INPUT of `{}`: `:=` gives an input its value before each run",
        "config-argument-not-an-input",
    ),
    (
        "`{}` is not a VAR_OUTPUT of `{}`: `=>` copies an output out after each run",
        "config-argument-not-an-output",
    ),
    (
        "`=>` copies to a variable: a global variable or a direct address (`%QX0.1`)",
        "config-argument-output-not-a-variable",
    ),
    (
        "a program instance's argument calls no FUNCTION: it is a constant, a global variable or a direct address",
        "config-argument-calls-a-function",
    ),
    (
        "`{}` is not a character of STRING: a STRING holds the characters of Windows-1252",
        "string-character-not-in-charset",
    ),
    (
        "VAR_GLOBAL belongs outside the POUs: declare globals at the top level of a file",
        "global-in-pou",
    ),
    ("a FUNCTION's variables cannot be {}", "function-retain"),
    ("`{}` is the FUNCTION's own name", "function-own-name"),
    ("VAR_EXTERNAL `{}` is `{}` but the VAR_GLOBAL is `{}`", "external-type-differs"),
    ("VAR_EXTERNAL `{}` must be CONSTANT like its VAR_GLOBAL", "external-not-constant"),
    ("VAR_EXTERNAL `{}` has no VAR_GLOBAL{}", "external-without-global"),
    ("only a PROGRAM's or a VAR_GLOBAL's variables can be located", "located-in-fb"),
    ("a VAR_IN_OUT or VAR_TEMP cannot be located", "located-temp"),
    ("a VAR_IN_OUT has no initial value", "in-out-initial-value"),
    (
        "only VAR, VAR_INPUT, VAR_IN_OUT, VAR_GLOBAL and VAR_EXTERNAL can be CONSTANT",
        "constant-output",
    ),
    ("the variables of `{}` need {} bytes of frame (limit 1 MiB)", "function-frame-too-large"),
    ("`{}` is `{}`: only elementary types and their arrays can be located", "located-struct"),
    ("`%{}` is {} {}-bit location, `{}` is `{}`", "iec-size-mismatch"),
    ("`%{}` is {} {}-bit location, `{}` a {}-bit type", "iec-size-mismatch-unnamed"),
    // a multi-level address `[iec.addresses]` places: its size letter's bits, as any address's
    ("`%{}` is {} {}-bit location, `{}` is `{}`", "iec-multi-level-placed-size"),
    ("`{}` needs {} bits from `{}`: past the end of its area", "bit-array-past-end"),
    ("`{}` needs {} words from `{}`: past the end of its area", "past-area-end"),
    ("`{}` needs {} bytes from `%{}`: past the end of its area", "bytes-past-area-end"),
    ("`{}` is the standard's enable {}: declare it `{} : BOOL` in {}", "enable-declaration"),
    ("`{}` belongs to a `BOOL` VAR_INPUT of a FUNCTION_BLOCK", "edge-not-fb-input"),
    // emit.rs: code generation
    ("this statement needs {} evaluation stack slots (limit {})", "statement-stack-too-deep"),
    ("`{}` needs {} bytes of frame (limit 1 MiB)", "statement-frame-too-large"),
    // expr.rs: expressions, places, calls
    (
        "VAR_IN_OUT `{}` of `{}`: an array or structure located at a device word cannot be passed by reference: copy it into a variable first",
        "in-out-at-device-words",
    ),
    ("a string constant is at most 255 characters", "string-constant-too-long"),
    ("unknown type `{}`", "typed-literal-unknown-type"),
    ("`{}#` needs a value name", "typed-literal-needs-name"),
    ("`{}` has no value `{}`{}", "no-enum-value"),
    ("`{}` has no input or output `{}`{}", "fb-no-such-member"),
    ("`{}` is not an input or output of `{}`", "fb-no-input-or-output"),
    ("`{}` is a VAR_OUTPUT of `{}`: it cannot be written here", "fb-output-not-writable"),
    ("`{}` has no members (looking for `{}`)", "no-members"),
    (
        "`{}.{}` is bound to a device (VAR_CONFIG, [iec.variables]): `{}` can be used only member by member",
        "struct-member-on-device-whole-use",
    ),
    ("an array index must be an integer, not `{}`", "index-not-integer"),
    ("`{}` has {} dimension(s), {} index(es) given", "wrong-dimensions"),
    ("index {} is out of the bounds `{}..{}`", "index-out-of-bounds"),
    ("`{}` is `{}`, not an array", "not-an-array"),
    ("a bit of a variable cannot be passed to a VAR_IN_OUT", "bit-to-in-out"),
    ("`{}` has no bit {}", "bit-out-of-range"),
    ("bit access needs an integer or bit string, not `{}`", "bit-of-non-integer"),
    ("a part of a variable cannot be passed to a VAR_IN_OUT", "partial-to-in-out"),
    ("partial access `{}` needs a variable", "partial-of-expression"),
    (
        "partial access `{}` needs a BYTE, WORD, DWORD or LWORD, not `{}`",
        "partial-of-non-bit-string",
    ),
    ("`{}` has no {} part: it is not wider than a `{}`", "partial-not-narrower"),
    ("`{}` has no {} part: it is not wider than a `{}`", "part-long-word"),
    ("`{}` has no {} {}: its {}s are `{}0` to `{}{}`", "partial-out-of-range"),
    ("only a variable can be assigned", "only-variable-assigned"),
    ("a VAR_IN_OUT argument must be a variable", "in-out-needs-variable"),
    ("`{}` is CONSTANT: it cannot be written", "constant-not-writable"),
    ("`{}` is at `{}`, which a program cannot write", "device-not-writable"),
    // for_written.rs: CODESYS's FOR variable written in the loop (a warning)
    (
        "`{}` is the FOR variable, written in the loop: the loop goes on from the value written, plus the step",
        "warning-for-variable-written",
    ),
    ("`{}` has no result type", "no-result-type"),
    ("`{}` is ambiguous: a value of {} (write `{}#{}`)", "ambiguous-enum-value"),
    ("`{}` is {}", "function-as-variable"),
    ("`{}` is not declared{}", "not-declared"),
    ("`{}` is not declared{}", "no-result"),
    ("constant `{}` is outside `{}`", "subrange-out"),
    ("type mismatch: {} cannot be assigned to `{}`{}", "type-mismatch"),
    ("`+` cannot be applied to `{}`", "unary-plus-operand"),
    ("`-` cannot be applied to `{}`", "neg-operand"),
    ("`NOT` cannot be applied to `{}`", "not-operand"),
    ("`{}` cannot be applied to `{}` and `{}`", "operator-types"),
    ("`{}` cannot be applied to `{}` and `{}`", "calendar-operator-types"),
    ("`{}` cannot be applied to `{}`", "operator-not-applicable"),
    ("`**` needs a `REAL` or `LREAL` base, not `{}`", "pow-base"),
    ("division by zero", "division-by-zero"),
    ("`{}` is a PROGRAM: a PROGRAM cannot be called", "program-called"),
    ("`{}` is a function block type: declare an instance and call that", "fb-type-called"),
    ("a function block call is a statement, not a value", "fb-call-as-value"),
    ("`{}` is not a function or a function block instance", "not-callable"),
    ("the call of `{}` mixes positional and named arguments", "mixed-arguments"),
    ("too many arguments for `{}` (it takes {})", "too-many-arguments"),
    ("`{}` is an output of `{}`: use `=>`", "output-with-assign"),
    ("`{}` is not a parameter of `{}`", "not-a-parameter"),
    ("`{}` is an input of `{}`: use `:=`", "input-with-arrow"),
    ("`NOT {} =>` needs a BOOL output", "negated-output-not-bool"),
    ("type mismatch: `{}` cannot be assigned to `{}`", "output-type-mismatch"),
    ("`{}` is given twice", "parameter-given-twice"),
    ("VAR_IN_OUT `{}` of `{}` needs a `{}` variable, not `{}`", "in-out-type"),
    ("the call of `{}` is missing VAR_IN_OUT `{}`", "missing-in-out"),
    // inout.rs: an FB instance's VAR_IN_OUT named outside its body
    (
        "`{}` is an `ARRAY [*]` VAR_IN_OUT of `{}`: it cannot be named outside the block's body",
        "open-array-in-out-outside",
    ),
    ("`{}` is an `ARRAY [*]` VAR_IN_OUT of `{}`: only a call binds it", "open-array-in-out-bound-outside"),
    (
        "`{}` is a VAR_IN_OUT of `{}`: from outside it is not written, only bound to a variable `v` by `{}.{} := v`, as by `{}({} := v)`",
        "in-out-written-outside",
    ),
    (
        "`{}.{} := v` binds VAR_IN_OUT `{}` of `{}` to the variable `v`, as `{}({} := v)` does: `v` cannot be a value",
        "in-out-bound-to-value",
    ),
    ("`{}` has no parameter `{}`{}", "unknown-parameter"),
    // calendar.rs: DATE, TOD, DT and their long forms
    ("`{}`: no conversion from {} to {}", "calendar-no-conversion"),
    // mod.rs: instances, call graph, linking
    ("no PROGRAM `{}` in `{}`: it declares no PROGRAM", "program-file-without-program"),
    ("no PROGRAM `{}` in `{}` (it declares {})", "unknown-pou"),
    ("`{}` declares no PROGRAM", "no-program"),
    ("`{}` declares more than one PROGRAM ({}): name one with `pou`", "several-programs"),
    ("recursive call: {}", "recursive-call"),
    ("`{}` nests calls {} deep (limit {})", "calls-nested-too-deep"),
    ("`{}` needs {} bytes of frame with its calls (limit 1 MiB)", "call-chain-frame-too-large"),
    (
        "`{}` needs {} evaluation stack slots with its calls (limit {}): a call inside an \
         expression keeps the caller's slots below the callee's",
        "call-chain-stack-too-deep",
    ),
    // refs.rs: references and pointers
    ("`{}` is `{}`, not a `REF_TO` or `POINTER TO`: `^` cannot be applied", "deref-not-reference"),
    ("`{}` is a `POINTER TO`: it takes one index, not {}", "pointer-index-count"),
    ("`{}` needs a variable", "ref-needs-variable"),
    ("`{}` needs a variable", "ref-init-not-a-variable"),
    // ref_init.rs: REF() and ADR() in initial values
    (
        "an input's initial value cannot be a reference (`REF`, `ADR`): the caller gives it; declare the variable in VAR and set it there",
        "ref-init-of-input",
    ),
    (
        "a CONSTANT's initial value cannot be a reference (`REF`, `ADR`): a constant is a constant expression, and a place is known only when the program runs; declare the reference in VAR",
        "ref-init-constant",
    ),
    (
        "`{}`: the initial values of `{}` take references, which plcd sets in an array of it only when the array's bounds are integer literals and it has no initialiser of its own; set them in the body",
        "ref-init-type-array",
    ),
    // generic_constants.rs: TwinCAT's generic constants
    ("`VAR_GENERIC` declares constants: write `VAR_GENERIC CONSTANT`", "generic-without-constant"),
    ("a generic constant has an integer type (`n : UINT := 10;`)", "generic-constant-not-integer"),
    (
        "a generic constant's initial value must be a constant integer expression",
        "generic-default-not-constant",
    ),
    (
        "`{}` is not a function block with generic constants (`VAR_GENERIC CONSTANT`): it takes no `<…>`",
        "generic-not-a-generic-block",
    ),
    ("`{}` has {} generic constant{} ({}), given {} argument{}", "generic-argument-count"),
    (
        "the value of `{}`'s generic constant `{}` must be a constant integer expression (literals, global constants, the POU's own constants and generic constants)",
        "generic-argument-not-constant",
    ),
    ("{} does not fit `{} : {}` of `{}`", "generic-argument-does-not-fit"),
    (
        "`{}` asks for copies of itself without end (its generic constants give an instance of it new values each time); more than {} were made",
        "generic-copies-without-end",
    ),
    ("`{}` takes one argument", "ref-one-argument"),
    ("`__ISVALIDREF` needs a reference, not `{}`", "isvalidref-not-reference"),
    ("`REF=` needs a reference on its left, not `{}`", "ref-assign-not-reference"),
    // stdlib.rs: standard functions
    ("`{}` has no output `{}`", "std-no-output"),
    ("the call of `{}` leaves out an argument", "std-argument-left-out"),
    ("`{}` takes {} argument(s), {} given", "std-arity"),
    ("`{}` needs {}, not `{}`", "std-argument-type"),
    ("`{}` takes no arguments", "std-no-arguments"),
    ("`{}` takes a task number from {} to {}, not {}", "task-number-range"),
    ("`{}` takes one task number or nothing", "task-number-arguments"),
    ("`{}` needs elementary values, not `{}`", "std-elementary-values"),
    ("`{}` needs a STRING, not `{}`", "std-string-argument"),
    (
        "`{}` cannot mix {} and {}: convert one with STRING_TO_WSTRING or WSTRING_TO_STRING",
        "string-kinds-mixed",
    ),
    ("`{}` needs {}, not `{}`", "string-conversion"),
    // stmt.rs: statements
    ("the condition of {} must be `BOOL`, not `{}`", "condition-not-bool"),
    ("`{}` has no result", "void-function-value"),
    ("`{}` outside a loop", "exit-outside-loop"),
    ("`{}` outside a loop", "continue-outside-loop"),
    ("the FOR variable `{}` must be an integer, not `{}`", "for-variable-not-integer"),
    ("the FOR variable `{}` must be a local variable of the POU", "for-variable-not-local"),
    (
        "the FOR variable `{}` must be a variable, or its member or element at constant indices",
        "for-element-not-fixed",
    ),
    // assign_expr.rs: an assignment inside an expression
    (
        "an assignment inside an expression takes an elementary value, not `{}`: assign it in a statement of its own",
        "assign-expr-aggregate",
    ),
    (
        "property `{}` is written by an assignment statement only (which calls its SET), not here",
        "property-written-in-expression",
    ),
    ("a FOR step of 0 never ends the loop", "for-step-zero"),
    ("a CASE selector must be an integer or an enumeration, not `{}`", "case-selector-type"),
    ("the CASE range `{}..{}` is empty", "empty-case-range"),
    ("duplicate CASE label `{}` (also at line {})", "duplicate-case-label"),
    ("CASE labels `{}` and `{}` overlap (line {})", "overlapping-case-labels"),
    ("a CASE label must be a constant", "case-label-not-constant"),
    ("a CASE label of type `{}` does not match the selector's type `{}`", "case-label-type"),
    // oop.rs: methods, properties, EXTENDS, interfaces
    ("`{}` is already declared in `{}`", "member-already-declared"),
    ("`{}` is ABSTRACT: only an ABSTRACT FUNCTION_BLOCK has ABSTRACT {}s (`{}` is not)", "abstract-member-of-concrete-block"),
    ("only a FUNCTION_BLOCK can EXTEND another", "extends-in-a-program"),
    ("`{}` is FINAL: it cannot be extended", "extends-a-final-block"),
    ("`{}` is not a FUNCTION_BLOCK: EXTENDS names the function block to extend", "extends-no-function-block"),
    ("`{}` is not an INTERFACE", "implements-no-interface"),
    ("no INTERFACE `{}` is declared{}", "implements-undeclared-interface"),
    ("`{}` extends itself through its bases", "extends-itself"),
    ("`{}` is used only inside a FUNCTION_BLOCK, its methods and actions", "this-outside-a-function-block"),
    ("`SUPER` needs a base: `{}` EXTENDS no function block", "super-without-extends"),
    ("`{}` is PRIVATE: only the code of `{}` may use it", "private-method-called"),
    ("`{}` is PRIVATE: only the code of `{}` may use it", "private-setter-written"),
    // qualified.rs: a global variable list's name and a library's namespace before a name
    ("the global variable list `{}` declares no `{}`", "gvl-declares-no-variable"),
    ("`{}` is a global of the list `{}`, which is {}: name it `{}`", "gvl-qualified-only"),
    ("`.{}` names a global, and no global is called `{}`", "global-scope-no-global"),
    ("`{}` is ambiguous: {} global variable lists declare it; name one, {}", "gvl-name-ambiguous"),
    ("`{}` is a value of the enumeration `{}`, which is {}: name it `{}` (or `{}#{}`)", "enum-qualified-only"),
    ("`{}` is PROTECTED: only the code of `{}` and of the function blocks extending it may use it", "protected-method-called"),
    ("`{}` is a variable of `{}`, not a method", "variable-called-as-method"),
    ("`{}` has no method `{}`", "method-not-found"),
    ("`{}` has no method `{}`", "interface-method-not-found"),
    ("`{}` is ABSTRACT: it has no body to call", "abstract-method-called"),
    ("property `{}` has no GET: it cannot be read", "property-without-get"),
    ("property `{}` is no variable: it cannot be passed to a VAR_IN_OUT (as in CODESYS, C0041: a VAR_IN_OUT needs a variable with write access); copy it into a variable first", "property-to-var-in-out"),
    ("property `{}` has no SET: it cannot be written", "property-without-set"),
    ("`{}` is FINAL: `{}` cannot override it", "final-method-overridden"),
    ("`{}` overrides `{}` with another signature: {}", "override-signature-differs"),
    ("`{}` does not implement {} of `{}`", "interface-member-missing"),
    ("`{}` implements `{}` with another signature: {}", "interface-signature-differs"),
    ("`{}` is ABSTRACT: it cannot be instantiated (extend it)", "abstract-block-instantiated"),
    ("`{}` compares interfaces: only `=` and `<>` do", "interface-ordered"),
    ("`{}` and `{}` cannot be compared", "interfaces-not-comparable"),
    ("`{}` has no property `{}`", "interface-property-not-found"),
    ("VAR_INST belongs to a METHOD (as in CODESYS, which allows it only in methods), not to a property's GET or SET: declare the variable in its function block", "var-inst-in-property"),
    // class.rs: CLASS
    ("`{}` is a CLASS: a class has no actions (write `{}` as a METHOD)", "class-has-action"),
    (
        "`{}` is a CLASS: a class declares no {} (it is never called: its methods take and give the values)",
        "class-declares-input",
    ),
    ("`{}` is a CLASS: a class has no body (its code is in its METHODs)", "class-has-body"),
    ("`{}` is a FUNCTION_BLOCK: a CLASS extends only a CLASS", "class-extends-function-block"),
    (
        "`{}` is a CLASS: an instance of a class is not called, its methods are (`inst.Method()`)",
        "class-called",
    ),
    // query.rs: __QUERYINTERFACE, __QUERYPOINTER
    ("`{}` takes two arguments, by position", "query-arguments"),
    ("`{}` asks an interface value, not `{}`", "query-source-not-interface"),
    ("`{}` writes its answer to an interface variable, not `{}`", "query-destination-not-interface"),
    ("`{}` writes its answer to a POINTER TO or REF_TO variable, not `{}`", "query-destination-type"),
    // fb_init.rs: FB_init
    (
        "an FB_init method declares `bInitRetains : BOOL` and `bInCopyCode : BOOL` as its first two VAR_INPUTs",
        "fb-init-signature",
    ),
    (
        "`{}`'s function block has an FB_init, which plcd does not run for a VAR_STAT's instance (one copy for every instance of its POU) nor a CONFIGURATION's VAR_GLOBAL's",
        "fb-init-static-instance",
    ),
    (
        "`{}`: declaration arguments go to FB_init, which plcd does not run for a VAR_STAT's instance, a CONFIGURATION's VAR_GLOBAL's, nor a VAR_IN_OUT or VAR_EXTERNAL",
        "fb-init-argument-not-run",
    ),
    (
        "{}: the declaration arguments are all named (`x := 5`) or all positional (`{}(5, 'A')`), not both",
        "fb-init-arguments-mixed",
    ),
    (
        "{}: a declaration argument gives an FB_init input (`{} := …`), not an output",
        "fb-init-argument-output",
    ),
    (
        "{}: `{}`'s FB_init takes {} argument(s) after bInitRetains and bInCopyCode",
        "fb-init-too-many-arguments",
    ),
    ("`{}` has no FB_init input `{}` for {}", "fb-init-argument-unknown"),
    ("`{}` has no FB_init input `{}` for {}", "heap-new-argument-unknown"),
    // fb_exit.rs: FB_exit
    (
        "an FB_exit method declares `bInCopyCode : BOOL` as its first VAR_INPUT",
        "fb-exit-signature",
    ),
    // sfc.rs: Sequential Function Charts
    (
        "FUNCTION `{}` cannot hold a sequential function chart: a FUNCTION keeps nothing between calls (use a FUNCTION_BLOCK or a PROGRAM)",
        "sfc-in-function",
    ),
    (
        "a statement in the body of `{}`, which is a sequential function chart: a body is statements or a chart, not both (put the statements in an ACTION)",
        "sfc-statement-beside-chart",
    ),
    (
        "a METHOD's variables cannot be PERSISTENT: declare the variable in its function block's `VAR PERSISTENT`",
        "method-persistent",
    ),
    ("a FUNCTION's variables cannot be {}", "function-persistent"),
    (
        "a VAR_TEMP is set at every call and cannot be PERSISTENT: declare the variable in `VAR PERSISTENT`",
        "temp-persistent",
    ),
    ("step `{}` is already declared at line {}", "sfc-step-already-declared"),
    ("transition `{}` is already declared at line {}", "sfc-transition-already-declared"),
    ("step `{}` is named twice in this transition", "sfc-step-named-twice-in-transition"),
    ("`{}`: no step of that name in this chart", "sfc-unknown-step"),
    ("PRIORITY takes an integer literal (0 is the highest priority)", "sfc-priority-not-integer"),
    (
        "a second INITIAL_STEP in one network: `{}` is linked to `{}` (line {}), and a network has exactly one",
        "sfc-second-initial-step",
    ),
    (
        "no INITIAL_STEP in the network of step `{}`: one of its steps must be the INITIAL_STEP",
        "sfc-no-initial-step",
    ),
    ("`{}` is no action qualifier: {}", "sfc-unknown-qualifier"),
    ("qualifier `{}` needs a duration: `{}({}, T#5s)`", "sfc-qualifier-needs-duration"),
    ("qualifier `{}` takes {}", "sfc-qualifier-takes-no-duration"),
    ("qualifier `{}` takes {}", "sfc-qualifier-takes-one-duration"),
    (
        "`{}` is a variable of type `{}`: an action association names an ACTION of `{}` or a BOOL variable",
        "sfc-action-variable-not-bool",
    ),
];

/// The messages of `[st] strict` (`src/core/st/dialect.rs`), one per CODESYS habit, and their
/// cases.
const STRICT_MESSAGES: &[(&str, &str)] = &[
    (
        "generic constants (`VAR_GENERIC CONSTANT`, `FB_Log<20>`) are TwinCAT 3.1.4026, not IEC 61131-3: declare one function block per size, or a constant the block's variables are sized by (`[st] strict` is on)",
        "strict-generic-constants",
    ),
    (
        "conditional compilation (`{}`, `{}`) is CODESYS's and TwinCAT's: IEC 61131-3 gives a pragma no meaning; keep the variant wanted (`[st] strict` is on)",
        "strict-conditional-pragma",
    ),
    (
        "`PERSISTENT` is TwinCAT's and CODESYS's: IEC 61131-3 writes `RETAIN` (`[st] strict` is on)",
        "strict-persistent",
    ),
    (
        "an empty declaration (a `;` alone) is not IEC 61131-3: remove the `;` (`[st] strict` is on)",
        "strict-empty-declaration",
    ),
    (
        "`=>` without a variable is not IEC 61131-3: leave out the outputs the call does not read (`[st] strict` is on)",
        "strict-empty-output",
    ),
    (
        "`:=` without a value is not IEC 61131-3: leave out the inputs the call does not give (`[st] strict` is on)",
        "strict-empty-input",
    ),
    (
        "a `,` after the last argument is not IEC 61131-3: remove it (`[st] strict` is on)",
        "strict-trailing-comma",
    ),
    (
        "an initial value is a constant expression in IEC 61131-3: assign the variable at the start of the body (`[st] strict` is on)",
        "strict-variable-initial-value",
    ),
    (
        "`;` expected after `{}` (IEC 61131-3 ends every statement with `;`; `[st] strict` is on)",
        "strict-no-semicolon-after-end",
    ),
    (
        "`;` expected after the type's declaration (IEC 61131-3 ends every type declaration with `;`; `[st] strict` is on)",
        "strict-no-semicolon-after-type",
    ),
    (
        "`VAR_STAT` is not IEC 61131-3: declare the variable in `VAR` of a PROGRAM, or as a VAR_GLOBAL (`[st] strict` is on)",
        "strict-var-stat",
    ),
    (
        "`VAR_INST` is not IEC 61131-3: declare the variable in the function block's `VAR` (`[st] strict` is on)",
        "strict-var-inst",
    ),
    (
        "`VAR_INPUT CONSTANT` is not IEC 61131-3: write `VAR_INPUT` (`[st] strict` is on)",
        "strict-constant-input",
    ),
    (
        "IEC 61131-3 reads only an instance's inputs and outputs from outside: pass the value out through a VAR_OUTPUT (`[st] strict` is on)",
        "strict-read-fb-internal",
    ),
    (
        "IEC 61131-3 names a VAR_IN_OUT only inside its function block's body: use the variable the call binds to it (`[st] strict` is on)",
        "strict-in-out-through-instance",
    ),
    (
        "IEC 61131-3 binds every VAR_IN_OUT at each call of a function block: give it again (`[st] strict` is on)",
        "strict-in-out-omitted",
    ),
    (
        "IEC 61131-3 gives a call's arguments all by position or all by name: name each one (`[st] strict` is on)",
        "strict-positional-then-named",
    ),
    (
        "IEC 61131-3 calls no CONSTANT function block instance, as a call writes it: pass it as a plain VAR_IN_OUT (`[st] strict` is on)",
        "strict-constant-instance-called",
    ),
    (
        "IEC 61131-3 gives a FUNCTION's name to its result, and a variable of the same name makes the POU's name ambiguous: rename the variable (`[st] strict` is on)",
        "strict-variable-named-as-function",
    ),
    (
        "IEC 61131-3 assigns no function block instance: copy the variables wanted one by one, or pass the instance as a VAR_IN_OUT (`[st] strict` is on)",
        "strict-instance-assignment",
    ),
    (
        "a FUNCTION's result is a value of a data type in IEC 61131-3, not a function block instance: return a STRUCT, or pass the instance as a VAR_IN_OUT (`[st] strict` is on)",
        "strict-instance-result",
    ),
    (
        "IEC 61131-3 declares no function block instance in a FUNCTION, which keeps no state: declare a FUNCTION_BLOCK, or pass the instance as a VAR_IN_OUT (`[st] strict` is on)",
        "strict-instance-in-function",
    ),
    (
        "an initial value is a constant expression in IEC 61131-3, and an instance's place is none: assign the instance in the block's code or in FB_init (`[st] strict` is on)",
        "strict-instance-initial-value",
    ),
    (
        "IEC 61131-3 converts no integer to an enumeration: give one of `__SYSTEM.TYPE_CLASS`'s values (`[st] strict` is on)",
        "strict-integer-to-type-class",
    ),
    (
        "`{}` is CODESYS's name of this input: IEC 61131-3 names it `{}` (`[st] strict` is on)",
        "strict-codesys-parameter",
    ),
    (
        "IEC 61131-3 has no arithmetic on bit strings: convert to an integer first, `WORD_TO_UINT(w) + 1` (`[st] strict` is on)",
        "strict-bit-arithmetic",
    ),
    (
        "IEC 61131-3 has no arithmetic between a bit string and a real: convert first, `BYTE_TO_REAL(b) * r` (`[st] strict` is on)",
        "strict-bit-with-real",
    ),
    (
        "IEC 61131-3 shifts bit strings only: `WORD_TO_INT(SHR(INT_TO_WORD(i), n))` (`[st] strict` is on)",
        "strict-integer-shift",
    ),
    (
        "IEC 61131-3 counts a shift with an integer: `SHR(w, BYTE_TO_USINT(n))` (`[st] strict` is on)",
        "strict-bit-shift-count",
    ),
    (
        "IEC 61131-3 raises a `REAL` or `LREAL` base only: `EXPT(INT_TO_REAL(i), n)` (`[st] strict` is on)",
        "strict-integer-expt",
    ),
    (
        "`TIME()` is CODESYS's clock, not IEC 61131-3: measure durations with the standard timers (`TON`) (`[st] strict` is on)",
        "strict-time-clock",
    ),
    (
        "the duration is beyond `LTIME`'s signed 64-bit nanoseconds (IEC 61131-3; CODESYS's and TwinCAT's unsigned `LTIME` goes to `LTIME#213503d23h34m33s709ms551us615ns`; `[st] strict` is on)",
        "strict-unsigned-ltime",
    ),
    ("`SIZEOF` is not IEC 61131-3 (`[st] strict` is on)", "strict-sizeof"),
    (
        "`{}` is TwinCAT's and CODESYS's dynamic memory; IEC 61131-3 has none: declare the instances, an array of them for a list (`[st] strict` is on)",
        "strict-dynamic-memory",
    ),
    (
        "a VAR_INPUT of a generic type (`ANY…`) is CODESYS: IEC 61131-3 keeps generic types to its standard functions; write one POU per type (`[st] strict` is on)",
        "strict-generic-input",
    ),
    ("`BIT` is CODESYS and TwinCAT, not IEC 61131-3: declare a `BOOL` (`[st] strict` is on)", "strict-bit"),
    (
        "IEC 61131-3 has no conversion between references and numbers: move a `POINTER TO` by `p + n` and compare pointers with each other (`[st] strict` is on)",
        "strict-pointer-integer",
    ),
    (
        "indexing a `POINTER TO` is CODESYS, not IEC 61131-3: move the pointer by bytes and dereference it, `(p + i * 2)^` for an INT (`[st] strict` is on)",
        "strict-pointer-index",
    ),
    (
        "IEC 61131-3 has `AND`, `OR` and `XOR` on BOOL and bit strings only: `INT_TO_WORD(i) AND 16#FF` (`[st] strict` is on)",
        "strict-bitwise-integer",
    ),
    (
        "IEC 61131-3 converts between bit strings and integers only explicitly: `BYTE_TO_INT(b)` (`[st] strict` is on)",
        "strict-implicit-conversion",
    ),
    (
        "the constant does not fit the other operand's type: IEC 61131-3 widens only explicitly, `INT_TO_DINT(i) * 60000` (`[st] strict` is on)",
        "strict-widened-literal",
    ),
    (
        "this BCD conversion is CODESYS's Util library: IEC 61131-3 writes `BYTE_BCD_TO_USINT`, `USINT_TO_BCD_BYTE` and the like (`[st] strict` is on)",
        "strict-util-bcd",
    ),
    (
        "`{}` is CODESYS, not IEC 61131-3, whose `AND` and `OR` evaluate both operands: nest the test, `IF p <> 0 THEN IF p^ > 0 THEN …` (`[st] strict` is on)",
        "strict-short-circuit",
    ),
    (
        "`UNION` is CODESYS, not IEC 61131-3, which has no type whose members share their bytes: declare a STRUCT (`[st] strict` is on)",
        "strict-union",
    ),
    (
        "`JMP` and labels are CODESYS in ST: IEC 61131-3 has them in IL only; write IF, WHILE, REPEAT or EXIT (`[st] strict` is on)",
        "strict-jump",
    ),
    (
        "IEC 61131-3 writes an enumeration's base type before its values: `BYTE (A, B)` (`[st] strict` is on)",
        "strict-enum-base-after-values",
    ),
    (
        "IEC 61131-3 names an enumeration's value with `#`: `E#Value` (`[st] strict` is on)",
        "strict-enum-dot-value",
    ),
    (
        "IEC 61131-3 converts `{}` to `{}` only explicitly, as the value may change: `{}_TO_{}(…)` (`[st] strict` is on)",
        "strict-lossy-conversion",
    ),
    (
        "IEC 61131-3 converts `{}` to `{}` only explicitly, as the value may change: `{}_TO_{}(…)` (`[st] strict` is on)",
        "strict-lossy-real-conversion",
    ),
    (
        "IEC 61131-3 converts `{}` to `{}` only explicitly, as the value may change: `{}_TO_{}(…)` (`[st] strict` is on)",
        "strict-lossy-integer-to-real",
    ),
    (
        "IEC 61131-3 adds a `TIME` to a `TOD` or a `DT`, not to a `DATE`: go through a `DT`, `DT_TO_DATE(ADD_DT_TIME(DATE_TO_DT(d), t))` (SUB_DT_TIME to subtract) (`[st] strict` is on)",
        "strict-date-arithmetic",
    ),
    (
        "IEC 61131-3 gives an enumeration's value no number to convert to: test the value, `CASE e OF E#A: i := 0; …` (`[st] strict` is on)",
        "strict-enum-to-integer",
    ),
    (
        "IEC 61131-3 forbids writing the FOR variable in the loop: count with a WHILE loop and a variable of its own (`[st] strict` is on)",
        "strict-for-variable-written",
    ),
    (
        "IEC 61131-3 counts in a variable named alone, not in an element or a member: count in a local variable and copy it (`[st] strict` is on)",
        "strict-for-element",
    ),
    (
        "IEC 61131-3 assigns in a statement only, not inside an expression: assign first, then use the variable, `b := FALSE; a := b;` (`[st] strict` is on)",
        "strict-assign-expr",
    ),
    (
        "unreachable `ELSE`: the labels cover every value of the selector's type; remove the `ELSE` (`[st] strict` is on)",
        "strict-covered-case-else",
    ),
    (
        "`.x`, the global scope operator, is CODESYS, not IEC 61131-3: name the global plainly, and rename the variable that hides it (`[st] strict` is on)",
        "strict-global-scope",
    ),
];

/// The messages of the IEC direct addresses' layouts (`src/core/device/iec.rs`, `[iec]`), and
/// their cases under `tests/golden`: `st/…` for a program's address, `config/…` for the layout
/// the config gives. Every message of that file is here or in [`IEC_PARTS`], and back.
const IEC_MESSAGES: &[(&str, &str)] = &[
    ("`%{}` is not a valid direct address", "st/bad-iec-address"),
    ("`%{}`: the openplc layout has no `%{}{}` (OpenPLC's inputs are %IX bits, %IB bytes and %IW words, its outputs %QX, %QB and %QW; `[iec] preset = \"codesys\"` has every size)", "st/iec-no-such-size"),
    ("`%{}` is past the end of the {} image: the {} layout's {} (`{}` to `{}`; `[iec] {}` moves it)", "st/iec-past-the-image"),
    ("`%{}`: bit {} of a byte: the {} layout numbers %{}X by byte and bit, the bit 0 to 7 (`%{}X{}.0` is the bit after `%{}X{}.7`; `[iec] preset = \"plcd\"` numbers P words and their bits 0 to 15)", "st/iec-bit-of-a-byte"),
    ("`%{}` is a multi-level address ({} levels), as Beremiz numbers an extension's I/O (its channel, then the extension's own items), and the config does not place it: add `\"%{}\" = \"…\"` to `[iec.addresses]` in the config, an address of the [iec] layout or a device of P, M, K or D (docs/CONFIG.md), or declare the variable `AT %{}{}*` and bind it with VAR_CONFIG or `[iec.variables]`", "st/iec-multi-level"),
    ("`{}` is not a device of P, M, K or D: an address is one of the [iec] layout or one of those devices", "config/iec-addresses-not-a-device-area"),
    ("`%{}` is itself a multi-level address: an entry places one at an address of the [iec] layout or at a device of P, M, K or D", "config/iec-addresses-target-multi-level"),
    ("`%{}` is {} {}-bit location, `{}` {} {}-bit one", "config/iec-addresses-size-mismatch"),
    ("`{}` and the {} word(s) after it hold `{}`: past the end of {} ({})", "config/iec-addresses-past-the-area"),
    ("`%{}` is not a multi-level address: an area letter (I, Q, M), a size letter (X, B, W, D, L), then numbers joined by dots, more than an address of the [iec] layout has (`%IX100.0.0`, `%IW100.0.1`, `%QW2.1`)", "config/iec-addresses-not-multi-level"),
    ("iec.addresses {}: no declaration, VAR_CONFIG, configuration, access path or [iec.variables] entry of the project names `{}`", "config/warning-iec-address-unused"),
    ("`{}` is not a word of P, M, K or D (an image starts at a word: `P064`, `D10000`)", "config/iec-start-not-a-word"),
    ("the {} image needs {} words from `{}`: past the end of {} ({})", "config/iec-image-past-the-area"),
    ("the {} image (`{}`, {} words) overlaps the {} image (`{}` to `{}`, `iec.{}`)", "config/iec-images-overlap"),
];

/// The texts of the layouts (`src/core/device/iec.rs`) and of what `plcd check` shows of them
/// (`src/core/st/iec_check.rs`) that are parts of messages or `plcd check`'s lines.
const IEC_PARTS: &[&str] = &[
    "%IXa.b, %QXa.b → bit b (0..15) of P word a; %IWa, %QWa → P word a",
    "%MXa.b → bit b of M word a; %MWa, %MDa, %MLa → M word a",
    "{}X0.0..{}X{}.7, {}B0..{}B{}, {}W0..{}W{}, {}D0..{}D{}, {}L0..{}L{}",
    "iec: the {} layout ([iec] preset), docs/ST.md \"Direct addresses\":",
    "iec: {}:{}: {}{} %{} → {}",
    // a byte address's device: its word and which half
    "{} ({})",
    // how a declaration or a configuration names the address, and a TASK's property
    " AT",
    " =>",
    " :=",
    "TASK {} {}",
    // what `plcd check` shows of `[iec.variables]` and `[iec.addresses]`
    "config: [iec.variables] {} AT %{} → {}",
    "config: [iec.addresses] {} →{} {}",
    " %{} →",
    "iec:   {}",
    "{} → {}..{} (iec.{})",
    "%{}X bytes are 0 to {}",
    "%{}B are 0 to {}",
    "%{}{} are 0 to {}",
    "{} are 0 to {}",
];

/// The messages of device addresses (`src/core/device/address.rs`) that the compiler passes on
/// for a variable's `AT %…`, and their cases.
const DEVICE_MESSAGES: &[(&str, &str)] = &[
    ("`{}` is not a device address", "bad-device"),
    ("`{}` is out of range ({})", "address-out-of-range"),
    ("unknown flag `{}`", "unknown-flag"),
    ("`{}` is a word device, a bit is needed here", "bit-needed"),
    ("`{}` is a bit device, a word is needed here", "word-needed"),
];

/// Messages of the compiler that no program can make it report, and why.
const UNREACHABLE: &[(&str, &str)] = &[
    (
        "the duration does not fit `TIME`",
        "the lexer already rejects a duration of more nanoseconds than an i64 holds",
    ),
    (
        "`__NOW` takes no arguments",
        "only the prelude may call `__NOW`, and it calls it without arguments",
    ),
    (
        "VAR_IN_OUT `{}` of `{}` needs a variable",
        "a place checked for a VAR_IN_OUT is a variable, an element or a member, or an error \
         reported already",
    ),
    (
        "`{}` is an `ARRAY [*]`: only its own POU indexes it",
        "an `ARRAY [*]` VAR_IN_OUT is named only in its own POU (from outside: `cannot be named \
         outside the block's body`), so an open array indexed is always that POU's own variable",
    ),
    (
        "this expression does nothing: a statement is needed",
        "the parser makes a statement of an expression only when the expression is a call",
    ),
];

/// Literals of the compiler sources that are not messages by themselves: words and hints that
/// messages are built from, and type names.
const PARTS: &[&str] = &[
    // what takes too much variable memory (decl.rs, given to memory_limit.rs)
    "the array",
    "an instance of `{}`",
    // where declaration arguments are given (fb_init.rs's check_arguments; heap.rs's __NEW)
    "the declaration of `{}`",
    "this `__NEW`",
    // the call of __FB_INIT_ALL in heap_new.st, which heap.rs extends with inputs
    "bInCopyCode := FALSE)",
    ", {} := {}",
    // what an access path's name is also, and what its path names (access_paths.rs)
    "a global variable",
    "the device `{}`",
    "the program instance `{}`",
    "a bit",
    "a word",
    "INT, UINT or WORD",
    "a VAR_TEMP",
    "a VAR_IN_OUT",
    "a VAR_EXTERNAL",
    // the pragma whose plain names are errors (qualified.rs)
    "attribute 'qualified_only'",
    // between the qualified forms of a name two lists declare (qualified.rs)
    " or ",
    // what a generic input was given instead of a variable (generic.rs)
    "a value",
    // what a UNION member cannot be (union.rs)
    "a function block instance",
    "an interface",
    "a `REFERENCE TO`",
    // what an interface's implementation lacks, and how a signature differs (oop.rs)
    "method `{}`",
    "the GET of property `{}`",
    "the SET of property `{}`",
    "its result is `{}`, not `{}`",
    "{} parameter(s), not {}",
    "parameter `{}` differs in name, kind or type",
    // what a qualifier takes after it (sfc.rs)
    "one duration, then indicator variable names",
    "no duration, only indicator variable names",
    // the kind of a string in messages (`needs a WSTRING`, `cannot mix a WSTRING and a STRING`)
    "a WSTRING",
    // the names of reference types in messages (`POINTER TO INT`)
    "POINTER TO",
    "REFERENCE TO",
    // the names of a DWORD and an LWORD part in the partial access messages (`has no double
    // word 2`)
    "double word",
    "long word",
    "{} {}",
    " (did you mean `{}`?)",
    "line {}",
    // who bound a variable first (var_config.rs), and the key an error about the config's
    // binding is about
    "[iec.variables] {}",
    "iec.variables {}: {}",
    "the configuration",
    "the project",
    "`{}` line {}",
    ", ",
    " and ",
    " → ",
    " (use {}_TO_{})",
    "integer constant `{}`",
    "a real constant",
    // what `{}` is, in "`{}` is {}"
    "a FUNCTION: call it with `(…)`",
    "a FUNCTION_BLOCK type, not a variable",
    "a PROGRAM, not a variable",
    // the argument counts of "`{}` takes {} argument(s), {} given"
    "at least {}",
    "{} to {}",
    // what a standard function needs, in "`{}` needs {}, not `{}`"
    "a number",
    "a `REAL` or `LREAL`",
    "a `REAL` or `LREAL` base",
    "a number exponent",
    "an integer selector",
    "a STRING",
    "a bit string (BYTE, WORD, DWORD, LWORD)",
    "an integer count",
    "a BOOL or bit string",
    "an integer",
    "an elementary value",
    "a variable or a type",
    // the loop of "the condition of {} must be `BOOL`, not `{}`"
    "REPEAT … UNTIL",
    // type names
    "{} ({}..{})",
    "ARRAY [{}] OF {}",
    "no value",
];

/// The message of a diagnostic line `file:line:col: error: message` (or `warning:`).
fn message(line: &str) -> Option<&str> {
    line.split_once(": error: ").or_else(|| line.split_once(": warning: ")).map(|(_, m)| m)
}

/// A format string with each `{…}` written `{}` (and `{{` `}}` as the braces they stand for).
fn template(format: &str) -> String {
    let mut out = String::new();
    let mut chars = format.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '{' if chars.peek() == Some(&'{') => {
                chars.next();
                out.push('{');
            }
            '}' if chars.peek() == Some(&'}') => {
                chars.next();
                out.push('}');
            }
            '{' => {
                for d in chars.by_ref() {
                    if d == '}' {
                        break;
                    }
                }
                out.push_str("{}");
            }
            c => out.push(c),
        }
    }
    out
}

/// The string literals of Rust source text up to its `#[cfg(test)]`, each with its line,
/// leaving out comments and the texts of `expect`, `unreachable!` and `panic!`.
fn literals(source: &str) -> Vec<(usize, String)> {
    let text = source.split("#[cfg(test)]").next().unwrap_or("");
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < chars.len() {
        match chars[i] {
            '\n' => line += 1,
            '/' if chars.get(i + 1) == Some(&'/') => {
                while i < chars.len() && chars[i] != '\n' {
                    i += 1;
                }
                continue;
            }
            // a char literal (`'"'`, `'\''`); a lifetime is passed over
            '\'' if chars.get(i + 1) == Some(&'\\') => {
                i += 3;
                while i < chars.len() && chars[i] != '\'' {
                    i += 1;
                }
            }
            '\'' if chars.get(i + 2) == Some(&'\'') => i += 2,
            '"' => {
                let (start, before) = (line, chars[..i].iter().collect::<String>());
                let mut lit = String::new();
                i += 1;
                while i < chars.len() && chars[i] != '"' {
                    if chars[i] == '\n' {
                        line += 1;
                    }
                    if chars[i] == '\\' {
                        i += 1;
                        match chars[i] {
                            'n' => lit.push('\n'),
                            't' => lit.push('\t'),
                            '\n' => {
                                line += 1;
                                while chars[i + 1].is_whitespace() {
                                    if chars[i + 1] == '\n' {
                                        line += 1;
                                    }
                                    i += 1;
                                }
                            }
                            c => lit.push(c),
                        }
                    } else {
                        lit.push(chars[i]);
                    }
                    i += 1;
                }
                let before = before.trim_end();
                let panics = ["expect(", "unreachable!(", "panic!("];
                if !panics.iter().any(|p| before.ends_with(p)) {
                    out.push((start, lit));
                }
            }
            _ => {}
        }
        i += 1;
    }
    out
}

/// The templates of the literals with a space in the compiler sources, each with where it is.
fn source_templates() -> Vec<(String, String)> {
    let mut files: Vec<_> = fs::read_dir(SOURCES)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .collect();
    files.sort();
    assert!(files.len() >= 7, "compiler sources missing under {SOURCES}");
    let mut out = Vec::new();
    for path in files {
        let source = fs::read_to_string(&path).unwrap();
        for (line, lit) in literals(&source) {
            if lit.contains(' ') {
                out.push((template(&lit), format!("{}:{line}", path.display())));
            }
        }
    }
    out
}

/// The messages of a case's `expected.stderr`.
fn case_messages(case: &str) -> Vec<String> {
    let path = Path::new(CASES).join(case).join("expected.stderr");
    let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines().filter_map(message).map(str::to_string).collect()
}

#[test]
fn every_row_case_reports_its_message() {
    let mut failures = Vec::new();
    for (template, case) in MESSAGES.iter().chain(DEVICE_MESSAGES).chain(STRICT_MESSAGES) {
        let messages = case_messages(case);
        // a message about an entry of the config's `[iec.variables]` starts with its key
        let own = |m: &str| match m.strip_prefix("iec.variables \"") {
            Some(rest) => rest.split_once("\": ").map_or(m.to_string(), |(_, m)| m.to_string()),
            None => m.to_string(),
        };
        if !messages.iter().any(|m| matches_template(template, &own(m))) {
            failures.push(format!("{case}: no message of `{template}` in {messages:?}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_message_of_the_compiler_is_listed() {
    let found = source_templates();
    let listed = |t: &str| {
        MESSAGES.iter().any(|(m, _)| *m == t)
            || UNREACHABLE.iter().any(|(m, _)| *m == t)
            || PARTS.contains(&t)
    };
    let unlisted: Vec<String> =
        found.iter().filter(|(t, _)| !listed(t)).map(|(t, at)| format!("{at}: \"{t}\"")).collect();
    assert!(
        unlisted.is_empty(),
        "messages with no golden case (add one, see this file's doc comment):\n{}",
        unlisted.join("\n")
    );
    let stale: Vec<&str> = MESSAGES
        .iter()
        .map(|(m, _)| *m)
        .chain(UNREACHABLE.iter().map(|(m, _)| *m))
        .chain(PARTS.iter().copied())
        .filter(|t| !found.iter().any(|(f, _)| f == t))
        .collect();
    assert!(stale.is_empty(), "listed but not in {SOURCES}: {stale:#?}");
}

#[test]
fn every_strict_message_is_in_the_dialect_source_and_back() {
    let source = fs::read_to_string("src/core/st/dialect.rs").unwrap();
    let found: Vec<String> = literals(&source)
        .into_iter()
        .map(|(_, l)| template(&l))
        .filter(|t| t.contains(' '))
        .collect();
    for (t, _) in STRICT_MESSAGES {
        assert!(found.iter().any(|f| f == t), "`{t}` is not a message of dialect.rs");
    }
    for f in &found {
        assert!(STRICT_MESSAGES.iter().any(|(t, _)| t == f), "dialect.rs: `{f}` has no case");
    }
}

#[test]
fn every_device_message_is_in_the_address_source() {
    let source = fs::read_to_string("src/core/device/address.rs").unwrap();
    let found: Vec<String> = literals(&source).into_iter().map(|(_, l)| template(&l)).collect();
    for (t, _) in DEVICE_MESSAGES {
        assert!(found.iter().any(|f| f == t), "`{t}` is not a message of address.rs");
    }
}

#[test]
fn every_message_of_the_iec_layouts_is_listed_and_shown() {
    // each file on its own: `literals` stops at a file's `#[cfg(test)]`
    let found: Vec<String> = ["src/core/device/iec.rs", "src/core/st/iec_check.rs"]
        .iter()
        .flat_map(|p| literals(&fs::read_to_string(p).unwrap()))
        .map(|(_, l)| template(&l))
        .filter(|t| t.contains(' '))
        .collect();
    let listed = |t: &str| IEC_MESSAGES.iter().any(|(m, _)| *m == t) || IEC_PARTS.contains(&t);
    let unlisted: Vec<&String> = found.iter().filter(|t| !listed(t)).collect();
    assert!(unlisted.is_empty(), "messages of the iec layouts with no row: {unlisted:#?}");
    let stale: Vec<&str> = IEC_MESSAGES
        .iter()
        .map(|(m, _)| *m)
        .chain(IEC_PARTS.iter().copied())
        .filter(|t| !found.iter().any(|f| f == t))
        .collect();
    assert!(stale.is_empty(), "listed but not in the iec layouts' sources: {stale:#?}");
    let mut failures = Vec::new();
    for (template, case) in IEC_MESSAGES {
        let path = Path::new("tests/golden").join(case).join("expected.stderr");
        let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // a config's message starts with the key it is about: `iec.input: …`
        let shown = text.lines().filter_map(message).any(|m| {
            matches_template(template, m)
                || m.split_once(": ").is_some_and(|(_, rest)| matches_template(template, rest))
        });
        if !shown {
            failures.push(format!("{case}: no message of `{template}`"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_case_is_the_case_of_a_row() {
    let mut orphans = Vec::new();
    for entry in fs::read_dir(CASES).unwrap() {
        let path = entry.unwrap().path();
        if !path.is_dir() {
            continue;
        }
        let case = path.file_name().unwrap().to_string_lossy().into_owned();
        let iec = IEC_MESSAGES.iter().any(|(_, c)| c.strip_prefix("st/") == Some(case.as_str()));
        if !iec
            && !MESSAGES
                .iter()
                .chain(DEVICE_MESSAGES)
                .chain(STRICT_MESSAGES)
                .any(|(_, c)| *c == case)
        {
            orphans.push(case);
        }
    }
    orphans.sort();
    assert!(orphans.is_empty(), "cases of no row in MESSAGES: {orphans:?}");
}

#[test]
fn the_scanner_reads_literals_and_templates() {
    let source = "let a = format!(\"`{name}` is {} {{x}}\"); // \"comment\"\n\
                  let c = '\"'; let d = '\\''; let l: &'a str = \"two words\";\n\
                  x.expect(\"a panic text\"); let e = \"long \\\n    line\";\n\
                  #[cfg(test)]\nmod tests { const T: &str = \"in a test\"; }";
    let lits = literals(source);
    let texts: Vec<(usize, String)> = lits.iter().map(|(l, t)| (*l, template(t))).collect();
    assert_eq!(
        texts,
        [
            (1, "`{}` is {} {x}".to_string()),
            (2, "two words".to_string()),
            (3, "long line".to_string()),
        ]
    );
    assert!(matches_template("`{}` has no bit {}", "`INT` has no bit 16"));
    assert!(!matches_template("`{}` has no result", "`f` has no result type"));
    assert!(matches_template("division by zero", "division by zero"));
    assert!(!matches_template("division by zero", "division by zeros"));
}
