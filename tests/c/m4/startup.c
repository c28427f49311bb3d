/* Bare-metal start for QEMU's mps2-an386 (Cortex-M4F): the vector table,
   .data and .bss set up, the FPU enabled, main called, and its status
   handed to QEMU by semihosting (SYS_EXIT_EXTENDED), which exits with it.
   Text goes out through SYS_WRITE0 (QEMU: -semihosting-config
   enable=on,target=native). */
#include <stdint.h>

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _stack_top;
int main(void);
void out_text(const char *s);
void reset(void);

static int semihost(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void out_text(const char *s) { (void)semihost(0x04, s); }

void reset(void)
{
    uint32_t *s = &_sidata, *d;
    uint32_t exit_block[2];
    for (d = &_sdata; d < &_edata;) *d++ = *s++;
    for (d = &_sbss; d < &_ebss;) *d++ = 0u;
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20; /* CPACR: CP10, CP11 full access */
    __asm__ volatile("dsb\n\tisb");
    exit_block[0] = 0x20026u; /* ADP_Stopped_ApplicationExit */
    exit_block[1] = (uint32_t)main();
    (void)semihost(0x20, exit_block);
    for (;;) {
    }
}

__attribute__((section(".vectors"), used)) static const uintptr_t vectors[2] = {(uintptr_t)&_stack_top, (uintptr_t)reset};
