; A worst-case BIOS, as an option ROM, for tests/hostile_bios.rs (assembled by
; boot/option_rom.rs with NASM; the checksum byte at the end is fixed there).
;
; At init (SeaBIOS calls a PnP ROM's entry at offset 3 during POST) it hooks
; INT 10h, 13h and 15h. Each hook chains to the BIOS's own handler as an INT
; would (the caller's flags pushed, IF clear), then returns to the caller
; with the low 16 bits of every register and the flags exactly as the BIOS
; returned them, and the upper 16 bits of EAX, EBX, ECX, EDX, ESI, EDI and EBP
; replaced by junk that changes on every call (bit 31 always set, so that it is
; never zero), as BIOSes that use 32-bit registers and save only the 16-bit
; halves do. Exceptions: E820 (INT 15h, AX=E820h) returns 32-bit values in
; EAX, EBX and ECX, which are left as the BIOS set them; INT 10h also replaces
; BP whole, as some video BIOSes do, except for AX=1130h, which returns ES:BP.
;
; Where its state lives, and why:
; - the BIOS's own vectors, saved at init, are in this ROM's shadow copy
;   (`old10` ...): SeaBIOS keeps the copy writable during POST and write-
;   protects it before it boots, so nothing the boot loader does can change
;   them afterwards. Writing them changes the ROM's checksum, which SeaBIOS
;   checks again after init (a ROM with a bad sum gets no boot entry), so
;   init fixes the sum (`checksum_fix`, the last byte).
; - the call counters and the junk generator's state change on every call,
;   after the ROM is read-only, so they live in the interrupt table's slots of
;   INT 60h-63h (0:0180h-0:018Fh), "reserved for user programs", which neither
;   the firmware nor the loader uses: a test reads the counters there (QMP
;   `pmemsave`) to prove the hooks ran.
;
; Variants (NASM -D): BEV=1 adds a Boot Entry Vector: booted from (QEMU's
; `-option-rom FILE,bootindex=0`), it reads sector 0 of drive 80h to 0:7C00
; itself and jumps to JUMP_SEG:JUMP_OFF (0000:7C00 or 07C0:0000) with
; DL=BOOT_DRIVE, and junk in the upper half of ESP and in every other
; register (the segment registers DS, ES, FS and GS too). The jump is said on
; COM1 first (JUMP_TEXT and DRIVE_TEXT name its target and DL).
; NO_EXTENSIONS=1 makes INT 13h a BIOS without the extensions (issue 48):
; AH=41h (installation check) returns CF set and AH=01h (invalid function),
; counted and said on COM1, without calling the BIOS.
; VIDEO_WAIT=1, 2 or 3 makes INT 10h AX=0013h (set mode 13h, which only the
; kernel asks for) wait first, as real video BIOSes and CSMs do inside a
; mode set (issue 66): 1 waits 1 ms through INT 15h AH=86h (which SeaBIOS
; times on the RTC's IRQ 8), 2 enables interrupts and waits for the BIOS
; tick at 0040:006Ch to move (IRQ 0), 3 enables interrupts and halts for
; ever. The waits begun and the waits ended are counted at 0:01A0h and
; 0:01A4h (INT 68h's and 69h's slots), and each begun wait is said on COM1.

bits 16
cpu 386
org 0

%include "pnp_rom.inc"

%ifndef BEV
%define BEV 0
%endif
%ifndef NO_EXTENSIONS
%define NO_EXTENSIONS 0
%endif
%ifndef VIDEO_WAIT
%define VIDEO_WAIT 0
%endif
%ifndef JUMP_SEG
%define JUMP_SEG 0x0000
%endif
%ifndef JUMP_OFF
%define JUMP_OFF 0x7C00
%endif
%ifndef BOOT_DRIVE
%define BOOT_DRIVE 0x80
%endif
%ifndef JUMP_TEXT
%define JUMP_TEXT '0000:7C00'
%endif
%ifndef DRIVE_TEXT
%define DRIVE_TEXT '80'
%endif

ROM_BYTES   equ 2048
COUNT10     equ 0x180           ; INT 60h's slot: INT 10h calls so far
COUNT13     equ 0x184           ; INT 61h's slot: INT 13h calls so far
COUNT15     equ 0x188           ; INT 62h's slot: INT 15h calls so far
SEED        equ 0x18C           ; INT 63h's slot: the junk generator's state
WAITS_BEGUN equ 0x1A0           ; INT 68h's slot: VIDEO_WAIT waits begun
WAITS_ENDED equ 0x1A4           ; and ended
FIRST_SEED  equ 0x2545F491      ; fixed: every run gets the same junk
COM1        equ 0x3F8

%if BEV
    PNP_ROM_HEADER 'hostile BIOS', bev
%else
    PNP_ROM_HEADER 'hostile BIOS', 0
%endif

; The BIOS's own vectors (offset, segment), written once by init.
old10: dd 0
old13: dd 0
old15: dd 0

; ---------------------------------------------------------------------------
; The hooks. HOOK name, old vector, counter, junk BP (0/1), keep EAX-ECX (0/1)
; ---------------------------------------------------------------------------

; Replaces the upper 16 bits of a 32-bit register with the current junk word
; (at 0:SEED+2, DS=0) xor a constant below 8000h (bit 15 stays set). Changes
; the flags, which the hook restores afterwards.
%macro JUNK_UPPER 3             ; 32-bit reg, its low 16-bit reg, constant
    ror %1, 16
    mov %2, [SEED + 2]
    or %2, 0x8000
    xor %2, %3
    ror %1, 16
%endmacro

%macro HOOK 5
%1:
    ; Give the BIOS the caller's flags, as an INT from the caller would.
    push bp
    mov bp, sp                  ; [bp]: BP, [bp+2]: IP, [bp+4]: CS, [bp+6]: flags
    push word [ss:bp + 6]
    popf                        ; the caller's flags
    pop bp                      ; (no flag changes from here to the call)
    pushf                       ; the INT frame's flags: the caller's
    cli                         ; as INT leaves them
    call far [cs:%2]            ; the BIOS irets (or retf 2): our frame is gone
    ; Here: registers and flags as the BIOS returned them.
    pushf
    push ds
    push eax
    push edx
    xor ax, ax
    mov ds, ax
    inc dword [%3]
    mov eax, [SEED]             ; the next junk: a 32-bit LCG step
    mov edx, 1103515245
    mul edx
    add eax, 12345
    mov [SEED], eax
    pop edx
    pop eax
%if %5 == 0
    JUNK_UPPER eax, ax, 0x0000
    JUNK_UPPER ebx, bx, 0x1111
    JUNK_UPPER ecx, cx, 0x2222
%endif
    JUNK_UPPER edx, dx, 0x3333
    JUNK_UPPER esi, si, 0x4444
    JUNK_UPPER edi, di, 0x5555
    JUNK_UPPER ebp, bp, 0x6666
%if %4
    mov bp, [SEED + 1]          ; BP whole: junk too
    or bp, 0x8001
%endif
    pop ds
    popf                        ; the BIOS's flags
    retf 2                      ; drop the caller's flags: return with the BIOS's
%endmacro

hook10:
%if VIDEO_WAIT
    cmp ax, 0x0013              ; set mode 13h: wait first
    jne .no_wait
    call video_wait
.no_wait:
%endif
    cmp ax, 0x1130              ; get font information: returns ES:BP
    je hook10_font
    jmp hook10_any
    HOOK hook10_any, old10, COUNT10, 1, 0
    HOOK hook10_font, old10, COUNT10, 0, 0

hook13:
%if NO_EXTENSIONS
    cmp ah, 0x41                ; are the extensions there?
    je hook13_no_extensions
%endif
    HOOK hook13_any, old13, COUNT13, 0, 0

%if NO_EXTENSIONS
; As a BIOS without them answers: CF set in the flags IRET restores, AH=01h
; (invalid function), every other register as the caller left it.
hook13_no_extensions:
    push bp
    mov bp, sp                  ; [bp+2]: IP, [bp+4]: CS, [bp+6]: flags
    or word [ss:bp + 6], 1      ; CF
    pop bp
    push ds
    push si
    xor si, si
    mov ds, si
    inc dword [COUNT13]
    mov si, msg_no_extensions
    call say
    pop si
    pop ds
    mov ah, 0x01
    iret
%endif

hook15:
    cmp ax, 0xE820              ; SeaBIOS looks at AX alone, so does this
    je hook15_e820
    jmp hook15_any
    HOOK hook15_any, old15, COUNT15, 0, 0
    HOOK hook15_e820, old15, COUNT15, 0, 1

%if VIDEO_WAIT
; The wait of a video BIOS's mode set, as the variant says; every register
; and the flags are kept.
video_wait:
    pushf
    push ds
    pushad
    xor ax, ax
    mov ds, ax
    inc dword [WAITS_BEGUN]
    mov si, msg_wait
    call say
%if VIDEO_WAIT == 1
    mov ah, 0x86                ; wait CX:DX microseconds
    xor cx, cx
    mov dx, 1000
    int 0x15
%elif VIDEO_WAIT == 2
    sti
    mov ax, [0x46C]             ; the BIOS tick's low word
.tick:
    cmp ax, [0x46C]
    je .tick
%else
    sti
.forever:
    hlt
    jmp .forever
%endif
    inc dword [WAITS_ENDED]
    popad
    pop ds
    popf
    ret
%endif

; ---------------------------------------------------------------------------
; Init: hook the three vectors (once), zero the counters, seed the junk.
; ---------------------------------------------------------------------------
init:
    pushf
    push ds
    push es
    pushad
    cli
    xor ax, ax
    mov ds, ax
    cmp word [0x13 * 4], hook13 ; called again? (SeaBIOS calls PnP init once)
    jne .hook
    mov ax, cs
    cmp [0x13 * 4 + 2], ax
    je .done
.hook:
    mov eax, [0x10 * 4]
    mov [cs:old10], eax
    mov eax, [0x13 * 4]
    mov [cs:old13], eax
    mov eax, [0x15 * 4]
    mov [cs:old15], eax
    mov word [0x10 * 4], hook10
    mov [0x10 * 4 + 2], cs
    mov word [0x13 * 4], hook13
    mov [0x13 * 4 + 2], cs
    mov word [0x15 * 4], hook15
    mov [0x15 * 4 + 2], cs
    mov dword [COUNT10], 0
    mov dword [COUNT13], 0
    mov dword [COUNT15], 0
    mov dword [SEED], FIRST_SEED
    mov dword [WAITS_BEGUN], 0
    mov dword [WAITS_ENDED], 0
    push cs
    pop ds
    call fix_checksums
    mov si, msg_hooked
    call say
.done:
    popad
    pop es
    pop ds
    popf
    retf

    PNP_ROM_ROUTINES

msg_hooked: db 'hostile-bios: INT 10h, 13h and 15h hooked', 10, 0
%if VIDEO_WAIT == 1
msg_wait: db 'hostile-bios: INT 10h AX=0013h: waiting 1 ms on INT 15h AH=86h', 10, 0
%elif VIDEO_WAIT == 2
msg_wait: db 'hostile-bios: INT 10h AX=0013h: waiting for the BIOS tick', 10, 0
%elif VIDEO_WAIT == 3
msg_wait: db 'hostile-bios: INT 10h AX=0013h: halting for ever', 10, 0
%endif
%if NO_EXTENSIONS
msg_no_extensions: db 'hostile-bios: INT 13h AH=41h: no extensions (CF set)', 10, 0
%endif

%if BEV
; ---------------------------------------------------------------------------
; The Boot Entry Vector: load the MBR ourselves, then jump with junk.
; ---------------------------------------------------------------------------
bev:
    sti
    push cs
    pop ds
    mov si, dap
    mov ah, 0x42
    mov dl, 0x80
    int 0x13
    jc .fail
    xor ax, ax
    mov es, ax
    cmp word [es:0x7DFE], 0xAA55
    jne .fail
    mov si, msg_bev
    call say
    ; Junk everywhere but CS:IP and DL.
    mov ax, 0x0700
    mov ss, ax
    mov esp, 0xBAD10400         ; SS:SP = 0700:0400, the upper half junk
    mov ax, 0x1357
    mov ds, ax
    mov ax, 0xF00D
    mov es, ax
    mov ax, 0x2468
    mov fs, ax
    mov ax, 0x8642
    mov gs, ax
    mov eax, 0xDEAD0E5E
    mov ebx, 0xFEEDBEEF
    mov ecx, 0xC0FFEE11
    mov edx, 0xBAADF000 | BOOT_DRIVE
    mov esi, 0x8BADF00D
    mov edi, 0xFACEB00C
    mov ebp, 0xD15EA5E5
    jmp JUMP_SEG:JUMP_OFF
.fail:
    mov si, msg_fail
    call say
.halt:
    hlt
    jmp .halt

dap:
    db 0x10, 0                  ; size, reserved
    dw 1                        ; one sector
    dw 0x7C00, 0x0000           ; to 0000:7C00
    dq 0                        ; LBA 0

msg_bev:
    db 'hostile-bios: BEV: MBR read, jumping to ', JUMP_TEXT
    db ' with DL=', DRIVE_TEXT, ' and junk in the upper halves', 10, 0
msg_fail: db 'hostile-bios: BEV: cannot read the MBR of drive 80h', 10, 0
%endif

    PNP_ROM_END
