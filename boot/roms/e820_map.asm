; E820 memory maps as firmware gets them wrong, for tests/memory_map.rs
; (issue 66; assembled by boot/option_rom.rs with NASM, which fixes the
; checksum byte at the end).
;
; At init (SeaBIOS calls a PnP ROM's entry at offset 3 during POST) it reads
; the BIOS's own E820 list (INT 15h, EAX=E820h) into a table in this ROM's
; shadow copy (writable during POST, like boot/roms/hostile_bios.asm's saved
; vectors), changes it as the variant says, and hooks INT 15h: from then on
; E820 calls are answered from the table, 20 bytes an entry, EBX the index
; of the next (0 after the last), CF set past the end; every other INT 15h
; call goes to the BIOS.
;
; Variants (NASM -D, any together):
; RESERVE_TOP=1 appends a reserved entry [top - 4 MiB, top - 2 MiB), where
;   top is the end of the usable entry that ends highest below 4 GiB: inside
;   it, where SMRAM, stolen graphics memory and ACPI NVS sit on real PCs. The
;   range is filled with PATTERN (through unreal mode: it lies far above
;   1 MiB) and its start and end are left in the interrupt table's slots of
;   INT 64h and 65h (0:0190h, 0:0194h), for a test to read back through QMP.
; TWICE=1 appends a copy of that usable entry: the list has it twice.
; REVERSE=1 answers the entries last first.
; NO_HIGH_RAM=1 makes every usable entry at or above 1 MiB reserved: a list
;   with no RAM the loader can use.
; E820 calls answered are counted at 0:0198h (INT 66h's slot).

bits 16
cpu 386
org 0

%include "pnp_rom.inc"

%ifndef RESERVE_TOP
%define RESERVE_TOP 0
%endif
%ifndef TWICE
%define TWICE 0
%endif
%ifndef REVERSE
%define REVERSE 0
%endif
%ifndef NO_HIGH_RAM
%define NO_HIGH_RAM 0
%endif

ROM_BYTES      equ 2048
MAX_ENTRIES    equ 32
ENTRY_BYTES    equ 20
RESERVED_START equ 0x190        ; INT 64h's slot
RESERVED_END   equ 0x194        ; INT 65h's slot
CALLS          equ 0x198        ; INT 66h's slot
PATTERN        equ 0xE820C0DE
SMAP           equ 0x534D4150
COM1           equ 0x3F8

    PNP_ROM_HEADER 'E820 map', 0

old15: dd 0                     ; the BIOS's INT 15h (offset, segment)
count: dd 0                     ; entries in the table

; ---------------------------------------------------------------------------
; The hook.
; ---------------------------------------------------------------------------
hook15:
    cmp eax, 0xE820
    jne .bios
    cmp edx, SMAP
    je .e820
.bios:
    jmp far [cs:old15]
.e820:
    push bp
    mov bp, sp                  ; [bp+2]: IP, [bp+4]: CS, [bp+6]: flags
    push ds
    push si
    push di
    push cx
    xor si, si
    mov ds, si
    inc dword [CALLS]
    cmp ebx, [cs:count]
    jae .past_the_end
%if REVERSE
    mov si, [cs:count]
    dec si
    sub si, bx
%else
    mov si, bx
%endif
    imul si, si, ENTRY_BYTES
    add si, table
    push cs
    pop ds
    mov cx, ENTRY_BYTES
    cld
    rep movsb                   ; to the caller's ES:DI
    pop cx
    pop di
    pop si
    pop ds
    inc ebx
    cmp ebx, [cs:count]
    jb .more
    xor ebx, ebx                ; that was the last
.more:
    mov eax, SMAP
    mov ecx, ENTRY_BYTES
    and word [bp + 6], 0xFFFE   ; CF clear in the flags IRET restores
    pop bp
    iret
.past_the_end:
    pop cx
    pop di
    pop si
    pop ds
    or word [bp + 6], 1         ; CF set
    pop bp
    iret

; ---------------------------------------------------------------------------
; Init: read the BIOS's list, change it, hook INT 15h (once).
; ---------------------------------------------------------------------------
init:
    pushf
    push ds
    push es
    pushad
    cli
    xor ax, ax
    mov ds, ax
    cmp word [0x15 * 4], hook15 ; called again?
    jne .read
    mov ax, cs
    cmp [0x15 * 4 + 2], ax
    je .done
.read:
    mov dword [RESERVED_START], 0
    mov dword [RESERVED_END], 0
    mov dword [CALLS], 0
    push cs
    pop es
    mov di, table
    xor ebx, ebx
    xor bp, bp                  ; entries read
.next:
    mov eax, 0xE820
    mov ecx, ENTRY_BYTES
    mov edx, SMAP
    push di
    push bp
    int 0x15
    pop bp
    pop di
    jc .read_all
    cmp eax, SMAP
    jne .read_all
    inc bp
    add di, ENTRY_BYTES
    test ebx, ebx
    jz .read_all
    cmp bp, MAX_ENTRIES - 2     ; room for the entries added below
    jb .next
.read_all:

%if NO_HIGH_RAM
    mov si, table
    mov cx, bp
.retype:
    cmp dword [cs:si + 16], 1
    jne .kept
    cmp dword [cs:si + 4], 0
    jne .make_reserved
    cmp dword [cs:si], 0x100000
    jb .kept
.make_reserved:
    mov dword [cs:si + 16], 2
.kept:
    add si, ENTRY_BYTES
    loop .retype
%endif

%if RESERVE_TOP || TWICE
    ; The usable entry that ends highest below 4 GiB: its end in EDX, its
    ; offset in BX.
    mov si, table
    mov cx, bp
    xor edx, edx
    xor bx, bx
.find:
    cmp dword [cs:si + 16], 1
    jne .not_it
    cmp dword [cs:si + 4], 0
    jne .not_it
    cmp dword [cs:si + 12], 0
    jne .not_it
    mov eax, [cs:si]
    add eax, [cs:si + 8]
    jc .not_it                  ; ends at 4 GiB or past it
    cmp eax, edx
    jbe .not_it
    mov edx, eax
    mov bx, si
.not_it:
    add si, ENTRY_BYTES
    loop .find
    test bx, bx
    jnz .found
    mov si, msg_no_top
    call say
    jmp .changed
.found:
%if TWICE
    push ds
    push cs
    pop ds
    mov si, bx
    mov cx, ENTRY_BYTES
    cld
    rep movsb                   ; a copy after the last entry (ES:DI)
    pop ds
    inc bp
%endif
%if RESERVE_TOP
    mov eax, edx
    sub eax, 0x400000
    mov [es:di], eax
    mov dword [es:di + 4], 0
    mov dword [es:di + 8], 0x200000
    mov dword [es:di + 12], 0
    mov dword [es:di + 16], 2
    add di, ENTRY_BYTES
    inc bp
    mov [RESERVED_START], eax
    add eax, 0x200000
    mov [RESERVED_END], eax
    call fill_reserved
%endif
.changed:
%endif

    mov [cs:count], bp
    mov word [cs:count + 2], 0
    mov eax, [0x15 * 4]
    mov [cs:old15], eax
    mov word [0x15 * 4], hook15
    mov [0x15 * 4 + 2], cs
    push ds
    push cs
    pop ds
    call fix_checksums
    pop ds
    mov si, msg_hooked
    call say
.done:
    popad
    pop es
    pop ds
    popf
    retf

%if RESERVE_TOP
; Fills [0:RESERVED_START], 2 MiB, with PATTERN: FS gets a 4 GiB limit in
; protected mode (unreal mode), then back in real mode the stores reach it.
; Interrupts are off (init's CLI); the BIOS's GDT is put back.
fill_reserved:
    pushad
    push fs
    o32 sgdt [cs:saved_gdtr]
    xor eax, eax
    mov ax, cs
    shl eax, 4
    add eax, gdt
    mov [cs:gdtr + 2], eax
    o32 lgdt [cs:gdtr]
    mov eax, cr0
    or al, 1
    mov cr0, eax
    jmp short .protected
.protected:
    mov bx, 8
    mov fs, bx
    and al, 0xFE
    mov cr0, eax
    jmp short .real
.real:
    xor bx, bx
    mov fs, bx
    o32 lgdt [cs:saved_gdtr]
    mov edi, [RESERVED_START]
    mov ecx, 0x200000 / 4
    mov eax, PATTERN
.store:
    mov [fs:edi], eax
    add edi, 4
    dec ecx
    jnz .store
    pop fs
    popad
    ret

    align 8
gdt:
    dq 0
    dq 0x00CF92000000FFFF       ; data: base 0, 4 GiB, writable
gdtr:
    dw 15
    dd 0                        ; the GDT's linear address, set above
saved_gdtr:
    dw 0
    dd 0
%endif

    PNP_ROM_ROUTINES

msg_hooked: db 'e820-rom: INT 15h E820 hooked', 10, 0
msg_no_top: db 'e820-rom: no usable entry ends below 4 GiB; list unchanged', 10, 0

table:
    times MAX_ENTRIES * ENTRY_BYTES db 0

    PNP_ROM_END
