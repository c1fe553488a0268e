//! OHCI 1.0a operational registers (chapter 7): their offsets in BAR0 and
//! the bits this driver uses, named as the specification names them.

/// HcRevision: BCD revision in bits 7:0 (0x10 for 1.0).
pub const HC_REVISION: u32 = 0x00;
/// HcControl: list enables, functional state, interrupt routing.
pub const HC_CONTROL: u32 = 0x04;
/// HcCommandStatus: reset, list filled, ownership change request.
pub const HC_COMMAND_STATUS: u32 = 0x08;
/// HcInterruptStatus: write 1 to clear.
pub const HC_INTERRUPT_STATUS: u32 = 0x0C;
/// HcInterruptEnable: write 1 to enable.
pub const HC_INTERRUPT_ENABLE: u32 = 0x10;
/// HcInterruptDisable: write 1 to disable.
pub const HC_INTERRUPT_DISABLE: u32 = 0x14;
/// HcHCCA: the physical address of the communication area.
pub const HC_HCCA: u32 = 0x18;
/// HcControlHeadED: the first ED of the control list.
pub const HC_CONTROL_HEAD_ED: u32 = 0x20;
/// HcControlCurrentED: where the controller is on the control list
/// (written only while ControlListEnable is clear).
pub const HC_CONTROL_CURRENT_ED: u32 = 0x24;
/// HcBulkHeadED: the first ED of the bulk list (unused: empty).
pub const HC_BULK_HEAD_ED: u32 = 0x28;
/// HcFmInterval: FrameInterval, FSLargestDataPacket, FrameIntervalToggle.
pub const HC_FM_INTERVAL: u32 = 0x34;
/// HcFmNumber: the frame counter (16 bits).
pub const HC_FM_NUMBER: u32 = 0x3C;
/// HcPeriodicStart: when in the frame periodic lists start.
pub const HC_PERIODIC_START: u32 = 0x40;
/// HcRhDescriptorA: port count, power switching, power-on time.
pub const HC_RH_DESCRIPTOR_A: u32 = 0x48;
/// HcRhStatus: global power.
pub const HC_RH_STATUS: u32 = 0x50;
/// HcRhPortStatus[1]; port n is at `HC_RH_PORT_STATUS + 4 * (n - 1)`.
pub const HC_RH_PORT_STATUS: u32 = 0x54;
/// The most root ports an OHCI root hub has (NDP is at most 15).
pub const MAX_ROOT_PORTS: u8 = 15;

/// HcControl.CBSR: 4 control EDs served per bulk ED.
pub const CONTROL_CBSR_4_TO_1: u32 = 3;
/// HcControl.PLE: periodic (interrupt) list enable.
pub const CONTROL_PLE: u32 = 1 << 2;
/// HcControl.CLE: control list enable.
pub const CONTROL_CLE: u32 = 1 << 4;
/// HcControl.HCFS: host controller functional state, bits 7:6.
pub const CONTROL_HCFS_MASK: u32 = 3 << 6;
/// HCFS UsbReset.
pub const HCFS_RESET: u32 = 0 << 6;
/// HCFS UsbResume.
pub const HCFS_RESUME: u32 = 1 << 6;
/// HCFS UsbOperational.
pub const HCFS_OPERATIONAL: u32 = 2 << 6;
/// HCFS UsbSuspend.
pub const HCFS_SUSPEND: u32 = 3 << 6;
/// HcControl.IR: interrupts routed to SMI (the firmware's SMM owns it).
pub const CONTROL_IR: u32 = 1 << 8;
/// HcControl.RWC: remote wakeup connected (kept as the firmware set it).
pub const CONTROL_RWC: u32 = 1 << 9;

/// HcCommandStatus.HCR: software reset (self-clearing, 10 us).
pub const COMMAND_HCR: u32 = 1 << 0;
/// HcCommandStatus.CLF: the control list has TDs.
pub const COMMAND_CLF: u32 = 1 << 1;
/// HcCommandStatus.OCR: ownership change request (to the OS).
pub const COMMAND_OCR: u32 = 1 << 3;

/// HcInterruptStatus.WDH: the done head was written to the HCCA.
pub const INTERRUPT_WDH: u32 = 1 << 1;
/// HcInterruptStatus.UE: unrecoverable error (the controller stopped).
pub const INTERRUPT_UE: u32 = 1 << 4;
/// HcInterruptStatus.RHSC: a root hub status change.
pub const INTERRUPT_RHSC: u32 = 1 << 6;
/// HcInterruptStatus.OC: ownership change (for SMM).
pub const INTERRUPT_OC: u32 = 1 << 30;
/// HcInterruptEnable/Disable.MIE: master interrupt enable.
pub const INTERRUPT_MIE: u32 = 1 << 31;
/// Every interrupt source (SO, WDH, SF, RD, UE, FNO, RHSC, OC) and MIE.
pub const INTERRUPT_ALL: u32 = 0x7F | INTERRUPT_OC | INTERRUPT_MIE;

/// HcFmInterval.FI: bit times in a frame, minus one.
pub const FM_INTERVAL_FI_MASK: u32 = 0x3FFF;
/// HcFmInterval.FSMPS: the largest full-speed packet that fits, bits 30:16.
pub const FM_INTERVAL_FSMPS_SHIFT: u32 = 16;
/// HcFmInterval.FSMPS's mask (after shifting).
pub const FM_INTERVAL_FSMPS_MASK: u32 = 0x7FFF;
/// HcFmInterval.FIT: toggled whenever FI is written.
pub const FM_INTERVAL_FIT: u32 = 1 << 31;
/// The nominal FrameInterval: 12,000 bit times, minus one.
pub const FRAME_INTERVAL_DEFAULT: u32 = 11_999;

/// HcRhDescriptorA.NDP: number of downstream ports, bits 7:0.
pub const RH_A_NDP_MASK: u32 = 0xFF;
/// HcRhDescriptorA.PSM: ports are powered each on its own.
pub const RH_A_PSM: u32 = 1 << 8;
/// HcRhDescriptorA.NPS: ports are always powered.
pub const RH_A_NPS: u32 = 1 << 9;
/// HcRhDescriptorA.POTPGT: power-on to power-good time, 2 ms units.
pub const RH_A_POTPGT_SHIFT: u32 = 24;

/// HcRhStatus write: SetGlobalPower (LPSC).
pub const RH_STATUS_SET_GLOBAL_POWER: u32 = 1 << 16;

/// HcRhPortStatus.CCS (read): a device is connected.
/// Write: ClearPortEnable.
pub const PORT_CCS: u32 = 1 << 0;
/// Write: ClearPortEnable.
pub const PORT_CLEAR_ENABLE: u32 = 1 << 0;
/// HcRhPortStatus.PES (read): the port is enabled.
pub const PORT_PES: u32 = 1 << 1;
/// HcRhPortStatus.PRS (read): a reset is under way. Write: SetPortReset.
pub const PORT_PRS: u32 = 1 << 4;
/// Write: SetPortPower.
pub const PORT_SET_POWER: u32 = 1 << 8;
/// HcRhPortStatus.LSDA (read): a low-speed device is attached.
pub const PORT_LSDA: u32 = 1 << 9;
/// HcRhPortStatus.CSC: connect status change (write 1 to clear).
pub const PORT_CSC: u32 = 1 << 16;
/// HcRhPortStatus.PESC: port enable status change (write 1 to clear).
pub const PORT_PESC: u32 = 1 << 17;
/// HcRhPortStatus.PSSC: port suspend status change (write 1 to clear).
pub const PORT_PSSC: u32 = 1 << 18;
/// HcRhPortStatus.OCIC: over-current indicator change (write 1 to clear).
pub const PORT_OCIC: u32 = 1 << 19;
/// HcRhPortStatus.PRSC: port reset status change (write 1 to clear).
pub const PORT_PRSC: u32 = 1 << 20;

/// HCCA offset of HccaDoneHead (bit 0: other interrupts pending too).
pub const HCCA_DONE_HEAD: u64 = 0x84;
/// HCCA entries of the interrupt table (one per frame, mod 32).
pub const HCCA_INTERRUPT_ENTRIES: usize = 32;
/// Bytes in the HCCA, and its alignment.
pub const HCCA_BYTES: u64 = 256;
