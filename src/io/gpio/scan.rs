//! The scan's side: one get-values ioctl refreshes every input and the key switch into the P
//! image, one set-values ioctl every output from it, in the plan's order and without
//! allocating.

use std::sync::Arc;

use gpiocdev::line::{Value, Values};
use gpiocdev::Request;

use super::error::errno;
use super::watchdog::OutputShared;
use super::{ImageBit, InputSlot};
use crate::device::Memory;
use crate::io::faults::FieldFaults;
use crate::io::{Io, SwitchPosition};

/// The scan's side of the backend: refreshes the P image from and to the lines.
#[derive(Debug)]
pub struct GpioIo {
    pub(super) inputs: Option<InputSide>,
    /// The key switch as last read (at open, then at each input refresh); `None`: no switch.
    pub(super) switch: Option<SwitchPosition>,
    pub(super) outputs: Option<OutputSide>,
    /// Where failed refreshes are counted, for the supervisor to log.
    pub(super) faults: Arc<FieldFaults>,
}

#[derive(Debug)]
pub(super) struct InputSide {
    pub request: Arc<Request>,
    /// Every input offset, sorted; gpiocdev fills in the values.
    pub values: Values,
    /// Where each entry of `values` goes: a P bit or the key switch.
    pub slots: Box<[InputSlot]>,
}

#[derive(Debug)]
pub(super) struct OutputSide {
    pub shared: Arc<OutputShared>,
    pub values: Values,
    pub bits: Box<[ImageBit]>,
}

impl Io for GpioIo {
    /// One get-values ioctl for all inputs and the key switch. On an error the P bits and the
    /// switch keep their last values, and the failure is counted (its errno, not the error:
    /// the error may hold a String, and describing it is the supervisor's).
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        let Some(inputs) = &mut self.inputs else { return };
        match inputs.request.values(&mut inputs.values) {
            Ok(()) => {
                self.faults.input_reads.worked();
                let switch = apply_inputs(mem.io_image_mut(), &inputs.slots, &inputs.values);
                if switch.is_some() {
                    self.switch = switch;
                }
            }
            Err(e) => self.faults.input_reads.failed(errno(&e).unwrap_or(0)),
        }
    }

    /// One set-values ioctl for all outputs.
    fn refresh_outputs(&mut self, mem: &Memory) {
        let Some(outputs) = &mut self.outputs else { return };
        collect_outputs(mem.io_image(), &outputs.bits, &mut outputs.values);
        match outputs.shared.request.set_values(&outputs.values) {
            Ok(()) => self.faults.output_writes.worked(),
            Err(e) => self.faults.output_writes.failed(errno(&e).unwrap_or(0)),
        }
    }

    /// The key switch as read at the last input refresh (or at open, before the first).
    fn switch(&self) -> Option<SwitchPosition> {
        self.switch
    }

    fn is_input(&self, bit: crate::device::BitRef) -> bool {
        self.inputs.as_ref().is_some_and(|inputs| {
            inputs.slots.iter().any(|slot| {
                matches!(slot, InputSlot::Bit { bit: b, .. } if b.word == bit.word && b.mask & bit.mask != 0)
            })
        })
    }
}

/// the key switch's position if it is among the lines.
fn apply_inputs(image: &mut [u16], slots: &[InputSlot], values: &Values) -> Option<SwitchPosition> {
    let mut switch = None;
    for (slot, lv) in slots.iter().zip(values.iter()) {
        match slot {
            InputSlot::Bit { bit, .. } => {
                if let Some(word) = image.get_mut(bit.word as usize) {
                    if lv.value == Value::Active {
                        *word |= bit.mask;
                    } else {
                        *word &= !bit.mask;
                    }
                }
            }
            InputSlot::Switch => switch = Some(position(lv.value)),
        }
    }
    switch
}

/// The key switch's position in line values (in offset order), if it is among the lines.
pub(super) fn switch_position(slots: &[InputSlot], values: &Values) -> Option<SwitchPosition> {
    let mut lines = slots.iter().zip(values.iter());
    lines.find(|(slot, _)| **slot == InputSlot::Switch).map(|(_, lv)| position(lv.value))
}

/// The switch's line is active at RUN (`active_low` is applied by the kernel).
fn position(value: Value) -> SwitchPosition {
    match value {
        Value::Active => SwitchPosition::Run,
        Value::Inactive => SwitchPosition::Stop,
    }
}

/// Sets each output's value (in offset order) from its P bit.
fn collect_outputs(image: &[u16], bits: &[ImageBit], values: &mut Values) {
    for (bit, lv) in bits.iter().zip(values.iter_mut()) {
        let on = image.get(bit.word as usize).is_some_and(|word| word & bit.mask != 0);
        lv.value = Value::from(on);
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::config::wiring::Wiring;
    use crate::device::layout::P_WORDS;

    /// The plan of a gpiocdev config with these inputs and outputs (device, line) and `extra`.
    fn plan(inputs: &[(&str, u32)], outputs: &[(&str, u32)], extra: &str) -> Wiring {
        let mut text = String::from(
            "[[program]]\nfile = \"main.il\"\n[io]\nbackend = \"gpiocdev\"\nchip = \"c\"\n",
        );
        for (kind, lines) in [("input", inputs), ("output", outputs)] {
            for (device, line) in lines {
                text += &format!("[[io.{kind}]]\ndevice = \"{device}\"\nline = {line}\n");
            }
        }
        text += extra;
        crate::config::parse(&text, Path::new("plcd.toml")).unwrap().wiring(&[]).unwrap()
    }

    fn values(offsets: &[u32], active: &[u32]) -> Values {
        let mut values = Values::from_offsets(offsets);
        for &offset in active {
            values.set(offset, Value::Active);
        }
        values
    }

    #[test]
    fn inputs_write_their_bits_only() {
        let plan = plan(&[("P0001", 9), ("P0000", 2), ("P0023", 5)], &[], "");
        let slots: Vec<_> = plan.inputs.iter().map(|i| i.slot).collect();
        let mut image = [0u16; P_WORDS as usize];
        image[0] = 0b1000_0001; // P0000 (an input, will go OFF) and P0007 (not an input)
        image[4] = 1; // P0040, an output
        let switch = apply_inputs(&mut image, &slots, &values(&[2, 5, 9], &[5, 9]));
        assert_eq!(image[0], 0b1000_0010);
        assert_eq!(image[2], 0b1000);
        assert_eq!(image[4], 1);
        assert_eq!(switch, None);
    }

    #[test]
    fn the_switch_line_is_read_with_the_inputs_into_no_bit() {
        let plan = plan(&[("P0001", 9), ("P0000", 2)], &[], "[switch]\nline = 4\n");
        let slots: Vec<_> = plan.inputs.iter().map(|i| i.slot).collect();
        let mut image = [0u16; P_WORDS as usize];
        let active = values(&[2, 4, 9], &[4]);
        assert_eq!(apply_inputs(&mut image, &slots, &active), Some(SwitchPosition::Run));
        assert_eq!(switch_position(&slots, &active), Some(SwitchPosition::Run));
        assert!(image.iter().all(|&w| w == 0), "no P bit for the switch: {:?}", &image[..1]);
        let inactive = values(&[2, 4, 9], &[2, 9]);
        assert_eq!(apply_inputs(&mut image, &slots, &inactive), Some(SwitchPosition::Stop));
        assert_eq!(switch_position(&slots, &inactive), Some(SwitchPosition::Stop));
        assert_eq!(image[0], 0b11);
        assert_eq!(switch_position(&slots[..0], &values(&[], &[])), None);
    }

    #[test]
    fn outputs_take_their_bits() {
        let plan = plan(&[], &[("P0041", 7), ("P0040", 3), ("P127F", 1)], "");
        let bits: Vec<_> = plan.outputs.iter().map(|o| o.bit).collect();
        let mut image = [0u16; P_WORDS as usize];
        image[4] = 0b10;
        image[127] = 0x8000;
        let mut v = values(&[1, 3, 7], &[3]);
        collect_outputs(&image, &bits, &mut v);
        assert_eq!(v.get(1), Some(Value::Active));
        assert_eq!(v.get(3), Some(Value::Inactive));
        assert_eq!(v.get(7), Some(Value::Active));
    }
}
