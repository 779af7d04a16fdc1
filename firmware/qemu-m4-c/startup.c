/* Start-up of the C firmware on QEMU mps2-an386 (Cortex-M4F): the vector table, the
 * reset handler (copy .data, zero .bss, enable the FPU, open the semihosting console,
 * run main, exit QEMU through semihosting with main's status) and a fault handler. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
extern void initialise_monitor_handles(void); /* newlib rdimon: semihosting stdio */
int main(void);

void reset_handler(void);
void fault_handler(void);

__attribute__((section(".vectors"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))&_estack, /* initial stack pointer */
    reset_handler,
    fault_handler, /* NMI */
    fault_handler, /* HardFault */
    fault_handler, /* MemManage */
    fault_handler, /* BusFault */
    fault_handler, /* UsageFault */
    0, 0, 0, 0,
    fault_handler, /* SVCall */
    fault_handler, /* DebugMonitor */
    0,
    fault_handler, /* PendSV */
    fault_handler, /* SysTick (never enabled as an interrupt) */
};

void reset_handler(void) {
    for (uint32_t *src = &_sidata, *dst = &_sdata; dst < &_edata;) *dst++ = *src++;
    for (uint32_t *dst = &_sbss; dst < &_ebss;) *dst++ = 0;
    /* CPACR: full access to CP10/CP11 (the FPU), before any float instruction. */
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;
    __asm volatile("dsb\n\tisb" ::: "memory");
    initialise_monitor_handles();
    exit(main());
}

void fault_handler(void) {
    printf("FAIL: fault exception\n");
    exit(1);
}

/* newlib's exit runs __libc_fini_array, which calls _fini (crti's, not linked with
 * -nostartfiles); nothing to finalise here. */
void _init(void) {}
void _fini(void) {}
