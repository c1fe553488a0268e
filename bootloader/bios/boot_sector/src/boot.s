# Patched (see ../../../CHANGES.md, "The boot path on real firmware"): the
# whole boot sector in assembly, after GRUB's boot.S. Upstream's Rust loop
# kept its state in 32-bit registers across `int 0x13`; a 16-bit BIOS owes
# nothing above bit 15, and one that changed them stopped the boot with `!a`.
# Here nothing lives in a register across a BIOS call: every call goes
# through `bios_disk` or `print_char`, which save all 32-bit registers, and
# the read loop keeps its state in memory.
#
# What it does:
# 1. Far-jumps to 0000:7C00, whatever CS:IP the BIOS used (07C0:0000 too).
# 2. Zeroes the segment registers; SS:ESP = 0000:00007000 (upper half clear),
#    the page boundary below this sector (boot-sector-link.ld).
# 3. Takes DL as the boot drive only where it names a hard disk (80h-8Fh),
#    as GRUB does; otherwise drive 80h (stage 2 says so).
# 4. Checks for the INT 13h extensions (LBA reads).
# 5. Reads stage 2 (the first partition) to 0000:7E00: each transfer at most
#    64 sectors and inside one 32 KiB block, so never over 127 sectors nor
#    across a 64 KiB boundary; each gets 3 tries, with a disk reset (AH=00h)
#    between them. A read that still fails is said on the screen and COM1,
#    with its LBA and the BIOS's status, and the machine waits.
# 6. Calls stage 2 as `_start(drive, partition table, report)` with the C
#    calling convention of the 16-bit target (32-bit arguments, a 32-bit
#    return address); `report` holds the reads retried (bits 0-7) and the DL
#    the BIOS gave (bits 8-15).

.section .boot, "awx"

.global _start
.code16

# Near calls and returns of 16 bits: LLVM's assembler makes 32-bit ones in
# 16-bit code, three bytes longer a call, that the sector has no room for.
.macro call16 target
    .byte 0xe8
    .word \target - (. + 2)
.endm
.macro ret16
    .byte 0xc3
.endm

_start:
    # jmp far 0000:normalised
    .byte 0xea
    .word normalised, 0x0000
normalised:
    xor ax, ax
    mov ds, ax
    mov es, ax
    mov fs, ax
    mov gs, ax
    # No interrupt comes between these two: `mov ss` holds them off for one
    # instruction.
    mov ss, ax
    # Patched: 0000:7000, off this sector's 4 KiB page (boot-sector-link.ld).
    mov esp, offset _stack_end
    sti
    cld

    # The boot drive: DL where it is a hard disk, else 80h. From here on DL
    # is the drive and DH the DL the BIOS gave.
    mov dh, dl
    mov al, dl
    and al, 0xf0
    cmp al, 0x80
    je 1f
    mov dl, 0x80
1:

    # INT 13h extensions (LBA packet reads): CF clear and BX = AA55h.
    mov ah, 0x41
    mov bx, 0x55aa
    call16 bios_disk
    jc no_extensions
    cmp bx, 0xaa55
    jne no_extensions

    # Stage 2 is the first partition. State kept in registers, which
    # `bios_disk` saves whole: DI the destination in 512-byte units (from
    # 0000:7E00), EBP the sectors left, BL the tries left, BH the reads
    # retried, ECX this transfer's sectors.
    mov si, offset dap
    mov eax, [0x7dbe + 8]
    mov [si + 8], eax
    mov ebp, [0x7dbe + 12]
    mov di, 0x7e00 / 512
    xor bh, bh
read_next:
    # Up to the end of the destination's 32 KiB block (64 sectors), and no
    # more than remain; the segment is the destination / 16, the offset 0.
    xor ecx, ecx
    mov ax, di
    and al, 63
    mov cl, 64
    sub cl, al
    cmp ecx, ebp
    jbe 1f
    mov ecx, ebp
1:
    mov ax, di
    shl ax, 5
    mov [si + 6], ax
    mov bl, 3
read_try:
    # The BIOS writes back the sectors it moved: set the count every try.
    mov [si + 2], cx
    mov ah, 0x42
    call16 bios_disk
    jnc read_done
    dec bl
    jz read_failed
    inc bh
    xor ah, ah
    call16 bios_disk
    jmp read_try
read_done:
    add [si + 8], ecx
    add di, cx
    sub ebp, ecx
    jnz read_next

    # Stage 2's entry: DL the drive, DH the DL the BIOS gave, CL the reads
    # retried.
    mov cl, bh
    movzx esp, sp
    jmp _second_stage_start

no_extensions:
    mov si, offset no_extensions_message
    jmp say_and_stop

read_failed:
    push ax
    mov si, offset read_failed_message
    call16 say
    mov eax, [dap + 8]
    mov cx, 8
    call16 print_hex
    # `say` left SI on the next string; `print_hex` keeps it.
    call16 say
    pop ax
    shl eax, 16
    mov cx, 2
    call16 print_hex
say_and_stop:
    call16 say
stop:
    cli
    hlt
    jmp stop

# INT 13h with AH, BX, DL, SI as set. AX and BX come back as the BIOS left
# them, and CF; every other register, all 32 bits, and DS and ES as before.
bios_disk:
    pushad
    push ds
    push es
    int 0x13
    pop es
    pop ds
    mov [esp + 28], ax
    mov [esp + 16], bx
    popad
    ret16

# Prints the zero-ended string at SI on the screen and COM1.
say:
    lodsb
    test al, al
    jz 1f
    call16 print_char
    jmp say
1:
    ret16

# Prints the top CX hex digits of EAX.
print_hex:
    rol eax, 4
    push eax
    and al, 0x0f
    # 0-9 to '0'-'9', 10-15 to 'A'-'F'.
    cmp al, 10
    sbb al, 0x69
    das
    call16 print_char
    pop eax
    loop print_hex
    ret16

# Prints AL on the screen (INT 10h, teletype) and on COM1, as the BIOS set
# COM1 up, waiting a bounded time for the UART: a PC without one loses the
# text, not the message.
print_char:
    pushad
    mov ah, 0x0e
    mov bx, 0x0007
    int 0x10
    mov dx, 0x3fd
    mov cx, 0xffff
1:
    in al, dx
    test al, 0x20
    loopz 1b
    mov dl, 0xf8
    # AL as given, from the registers `pushad` saved.
    mov al, [esp + 28]
    out dx, al
    popad
    ret16

no_extensions_message:
    .asciz "\r\nloader: no INT 13h extensions\r\n"
# Printed one after the other, in this order.
read_failed_message:
    .asciz "\r\nloader: cannot read the disk at LBA 0x"
    .asciz " (BIOS status 0x"
    .asciz "): write the stick again or use another USB port\r\n"

# The disk address packet: 16 bytes, LBA above 2^32 always 0.
dap:
    .byte 0x10, 0
    .word 0, 0, 0
    .long 0, 0
