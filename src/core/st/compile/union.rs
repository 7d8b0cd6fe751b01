//! CODESYS's `UNION … END_UNION` (docs/ST.md, "Unions"): a type whose members all start at
//! byte 0 of the same memory, its size that of its largest member. Writing one member and
//! reading another reads the same bytes as the other type, little-endian, as CODESYS does on
//! x86 and ARM.
//!
//! A union is laid out as a [`StructTy`] whose members are all at offset 0
//! ([`StructTy::union`]), so member access, copies, parameters and arrays of unions are the
//! struct's. This is sound with the existing ops because every variable lives in byte-addressed
//! memory, loaded and stored little-endian by type (`vm::typed`), and native code forgets a
//! value it holds in a register when a store overlaps its bytes, whatever the types
//! (`plcd-native`'s `carry::may_change`).
//!
//! What cannot be reinterpreted safely is refused: a function block instance or an interface
//! (their hidden type tag would be forged by another member's bytes) and a `REFERENCE TO`
//! (bound once, then used without a check of its own), alone or inside an array or struct
//! member. Pointers (`POINTER TO`, `REF_TO`) are accepted: every access through one is checked
//! at run time, whatever bytes made it.
//!
//! A `STRING` or `WSTRING` member may share the room for its terminating zero with another
//! member (TcUnit's `U_ExpectedOrActual` holds a `STRING(255)` and a `WSTRING(255)`): what is
//! read of it is bounded by its capacity ([`Ctx::open_union_string`], the emitter's bounded
//! copy), and it is not passed to a VAR_IN_OUT, where it would be read as any string is.

use crate::st::ast::{RefKind, TypeDecl, VarDecl};
use crate::st::dialect::Habit;

use super::ctx::{Ctx, Scope};
use super::expr::{TExpr, TK};
use super::types::{Member, StructTy, Ty};

impl<'a> Ctx<'a> {
    /// Lays out the UNION `decl` (type declaration `t`): its members at offset 0, its size the
    /// largest's, its initial image that of the member given an initial value, or else of the
    /// first member, zero-padded.
    pub(super) fn union_type(
        &mut self,
        t: usize,
        decl: &'a TypeDecl,
        members: &'a [VarDecl],
        scope: Scope,
    ) -> Ty {
        let file = scope.file;
        self.habit(Habit::Union, file, decl.span);
        // its index first, for the references to it among its members
        let index = self.types.structs.len();
        let name = decl.name.name.clone();
        let empty = StructTy {
            name: name.clone(),
            members: Vec::new(),
            size: 0,
            image: Vec::new(),
            union: true,
        };
        self.types.structs.push(empty);
        self.type_decls[t].ty = Ty::Struct(index);
        let mut out: Vec<Member> = Vec::new();
        let mut image: Vec<u8> = Vec::new();
        let mut initialized: Option<&str> = None;
        for m in members {
            // a `BIT` member is a `BOOL` as in a STRUCT (TwinCAT's, TcUnit's unions have one)
            let ty = self.member_type(&m.ty, scope);
            if let Some(loc) = &m.location {
                self.error(file, loc.span, "a UNION member cannot be located");
            }
            if let Some(what) = self.not_reinterpretable(&ty) {
                self.error(
                    file,
                    m.span,
                    format!("a UNION member cannot be {what}: other members' bytes would forge it"),
                );
            }
            for id in &m.names {
                if out.iter().any(|x| id.is(&x.name)) {
                    self.error(
                        file,
                        id.span,
                        format!("`{}` is already declared in this UNION", id.name),
                    );
                    continue;
                }
                if m.init.is_some() {
                    if let Some(first) = initialized {
                        self.error(
                            file,
                            id.span,
                            format!("only one member of a UNION can have an initial value, and `{first}` has one"),
                        );
                        continue;
                    }
                }
                let bytes = self.init_image(&ty, Some(&m.ty), m.init.as_ref(), scope, &id.name);
                // the first member's image, unless one is given an initial value (a second
                // one was refused above); zero-padded to the union's size below
                if out.is_empty() || m.init.is_some() {
                    image = bytes;
                }
                if m.init.is_some() {
                    initialized = Some(&id.name);
                }
                out.push(Member {
                    name: id.name.clone(),
                    ty: ty.clone(),
                    offset: 0,
                    partial: false,
                    device: None,
                });
            }
        }
        self.check_string_ends(&out, members, file);
        let size = out.iter().map(|m| self.types.size(&m.ty)).max().unwrap_or(0);
        image.resize(size as usize, 0);
        self.types.structs[index] = StructTy { name, members: out, size, image, union: true };
        Ty::Struct(index)
    }

    /// Refuses an array or STRUCT member holding a `STRING` or `WSTRING` whose room for its
    /// terminating zero another member's bytes cover. A string member itself may be
    /// overlapped: every read of it is bounded by its capacity ([`Ctx::open_union_string`]).
    /// A string inside a member is not, as that member's value is copied whole, by its bytes,
    /// into variables of its own type, whose strings are read up to their first zero unit.
    fn check_string_ends(&mut self, out: &[Member], members: &[VarDecl], file: usize) {
        for (i, m) in out.iter().enumerate() {
            if m.ty.string_cap().is_some() {
                continue;
            }
            let Some(end) = self.first_string_end(&m.ty, 0) else { continue };
            let over =
                out.iter().enumerate().find(|(j, o)| *j != i && self.types.size(&o.ty) > end);
            if let Some((_, other)) = over {
                let span = members
                    .iter()
                    .flat_map(|d| &d.names)
                    .find(|id| id.is(&m.name))
                    .map_or_else(Default::default, |id| id.span);
                let msg = format!(
                    "`{}` holds a string whose terminating zero `{}` overlaps: a string inside an array or STRUCT member of a UNION must end past every other member",
                    m.name, other.name
                );
                self.error(file, span, msg);
            }
        }
    }

    /// When `e` is a `STRING[n]` or `WSTRING[n]` member of a UNION whose room for its
    /// terminating zero the bytes of another member of a different type cover (so that no
    /// zero may end its characters): `n` and whether it is a WSTRING. Such a string's value is
    /// its characters up to the first zero among its `n`, or all `n`: the emitter reads it
    /// through a bounded copy, never past its own bytes.
    pub(super) fn open_union_string(&self, e: &TExpr) -> Option<(u32, bool)> {
        let TK::Member(base, 0, _) = &e.k else { return None };
        let Ty::Struct(s) = base.ty else { return None };
        let union = &self.types.structs[s];
        if !union.union {
            return None;
        }
        let cap = e.ty.string_cap()?;
        let end = if e.ty.is_wide() { 2 * cap } else { cap };
        let overlapped = union.members.iter().any(|m| m.ty != e.ty && self.types.size(&m.ty) > end);
        overlapped.then_some((cap, e.ty.is_wide()))
    }

    /// Refuses to pass an overlapped string member of a UNION ([`Ctx::open_union_string`])
    /// to a VAR_IN_OUT: the callee would read it as any string, up to its first zero unit,
    /// which may lie past the member.
    pub(super) fn refuse_open_string_in_out(&mut self, e: &TExpr, file: usize) {
        if self.open_union_string(e).is_some() {
            self.error(
                file,
                e.span,
                "a string member of a UNION that another member overlaps cannot be passed to a VAR_IN_OUT: other members' bytes may leave it without its terminating zero; pass a copy",
            );
        }
    }

    /// The byte offset, from `base`, of the room for the terminating zero of the first string
    /// `ty` holds (the string ending first), if it holds any.
    fn first_string_end(&self, ty: &Ty, base: u32) -> Option<u32> {
        match ty {
            Ty::Str(n) => Some(base + n),
            Ty::WStr(n) => Some(base + 2 * n),
            Ty::Array(a) => self.first_string_end(&a.of, base),
            Ty::Struct(s) => self.types.structs[*s]
                .members
                .iter()
                .filter_map(|m| self.first_string_end(&m.ty, base + m.offset))
                .min(),
            _ => None,
        }
    }

    /// What `ty` holds that a union cannot: a function block instance, an interface or a
    /// `REFERENCE TO`, as the message names it.
    fn not_reinterpretable(&self, ty: &Ty) -> Option<&'static str> {
        match ty {
            Ty::Fb(_) => Some("a function block instance"),
            Ty::Iface(_) => Some("an interface"),
            Ty::Ref(RefKind::Reference, _) => Some("a `REFERENCE TO`"),
            Ty::Array(a) => self.not_reinterpretable(&a.of),
            Ty::Struct(s) => {
                self.types.structs[*s].members.iter().find_map(|m| self.not_reinterpretable(&m.ty))
            }
            _ => None,
        }
    }
}
