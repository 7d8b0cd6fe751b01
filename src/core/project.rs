//! A project: the config and every program it names, loaded and checked together, with the
//! rules that span programs (the DUTY limits of the FX5 manual, edge memory, `DI n` numbers).

use std::path::{Path, PathBuf};

use crate::config::{Config, TaskRef};
use crate::device::{layout, Address, Area};
use crate::diag::{Diagnostic, Diagnostics};
use crate::lang::ops::Written;
use crate::lang::{self, Context, DutySite, Program};

/// FX5: "The DUTY instruction can be used up to 5 times (points)".
pub const MAX_DUTY: usize = 5;

/// A loaded, fully checked project.
#[derive(Debug, Clone)]
pub struct Project {
    pub config: Config,
    /// The programs, in the order of the config's `[[program]]` entries.
    pub programs: Vec<Program>,
}

impl Project {
    /// The outputs, in address order: every P bit a program writes (a word written whole
    /// counts as its 16 bits) and every configured `[[io.output]]`. The default watch list of
    /// traces and logs.
    pub fn output_bits(&self) -> Vec<Address> {
        let mut words = [0u16; layout::P_WORDS as usize];
        let p_end = layout::P_WORDS as u16;
        for program in &self.programs {
            for op in program.code.iter() {
                match op.writes() {
                    Some(Written::Bit(b)) if b.word < p_end => words[b.word as usize] |= b.mask,
                    Some(Written::Word(w)) if w.0 < p_end => words[w.0 as usize] = 0xFFFF,
                    Some(Written::DoubleWord(w)) => {
                        for word in [w.0, w.0.wrapping_add(1)].into_iter().filter(|&w| w < p_end) {
                            words[word as usize] = 0xFFFF;
                        }
                    }
                    _ => {}
                }
            }
        }
        for line in &self.config.io.outputs {
            if let Some(bit) = line.device.bit {
                words[line.device.number as usize] |= 1 << bit;
            }
        }
        let mut bits = Vec::new();
        for (word, mask) in words.iter().enumerate() {
            for bit in 0..16u8 {
                if mask & 1 << bit != 0 {
                    bits.push(Address { area: Area::P, number: word as u32, bit: Some(bit) });
                }
            }
        }
        bits
    }
}

/// Assembles the programs of an already parsed config; `read` supplies each program's text.
pub fn from_config(
    config: Config,
    read: impl Fn(&Path) -> std::io::Result<String>,
) -> Result<Project, Diagnostics> {
    let mut diags = Diagnostics::default();
    let task_numbers: Vec<u8> = config.tasks.iter().map(|t| t.number).collect();
    let timer_base = |n: u32| config.timers.base_ms(n);
    let mut programs = Vec::with_capacity(config.programs.len());
    let mut duty_sites = Vec::new();
    let mut edge_base = 0u32;
    for entry in &config.programs {
        let source = match read(&entry.resolved) {
            Ok(text) => text,
            Err(e) => {
                diags.push(Diagnostic::new(
                    &config.path,
                    entry.line,
                    entry.col,
                    format!(
                        "program \"{}\": cannot read `{}`: {e}",
                        entry.name,
                        entry.resolved.display()
                    ),
                ));
                continue;
            }
        };
        let ctx = Context {
            is_init: entry.task == TaskRef::Init,
            task_numbers: &task_numbers,
            timer_base_ms: &timer_base,
            edge_base,
        };
        let (program, sites) =
            lang::assemble_with_duty_sites(&entry.name, &entry.resolved, &source, &ctx);
        duty_sites.push((entry.resolved.clone(), sites));
        match program {
            Ok(program) => {
                edge_base += program.edge_slots;
                programs.push(program);
            }
            Err(d) => diags.extend(d),
        }
    }
    check_duty(&duty_sites, &mut diags);
    // Grouped by file, in line order, whatever the order they were found in.
    diags.0.sort();
    if diags.is_empty() {
        Ok(Project { config, programs })
    } else {
        Err(diags)
    }
}

/// At most five DUTY instructions, and one per clock relay, across the whole project. Five
/// relays with one DUTY each make five; the limit of five bites when a relay is named twice as
/// well (six DUTYs, one of them a duplicate: both errors).
fn check_duty(files: &[(PathBuf, Vec<DutySite>)], diags: &mut Diagnostics) {
    let mut seen: Vec<(u8, &Path, u32)> = Vec::new();
    for (path, sites) in files {
        for site in sites {
            let relay = 420 + u32::from(site.channel);
            if let Some((_, first_path, first_line)) =
                seen.iter().find(|(c, _, _)| *c == site.channel)
            {
                diags.push(Diagnostic::new(
                    path,
                    site.line,
                    site.col,
                    format!(
                        "SM{relay} is already the clock relay of the DUTY at {}:{first_line}: one DUTY per relay",
                        first_path.display()
                    ),
                ));
            } else if seen.len() >= MAX_DUTY {
                diags.push(Diagnostic::new(
                    path,
                    site.line,
                    site.col,
                    format!("more than {MAX_DUTY} DUTY instructions in the project"),
                ));
            }
            seen.push((site.channel, path, site.line));
        }
    }
}
