/* Bare-metal startup for a Cortex-M4F on QEMU's mps2-an386 (dfeif-codegen test harness).
 *
 * The vector table goes first in flash (the core reads the initial stack pointer and the reset
 * vector from address 0). The reset handler copies .data from flash to RAM, turns the FPU on
 * (hard-float code faults without it) and hands over to newlib's _start, which zeroes .bss, sets
 * up semihosting stdio and calls main; main's return value becomes QEMU's exit code.
 * Any fault ends the emulation with a semihosting exit instead of hanging until the timeout. */
#include <stdint.h>

extern uint32_t __stack_top, __data_load, __data_start, __data_end;
extern void _start(void);
void Reset_Handler(void);
void Fault_Handler(void);

__attribute__((section(".vectors"), used))
void (*const vector_table[16])(void) = {
    (void (*)(void))(&__stack_top),
    Reset_Handler,
    Fault_Handler, /* NMI */
    Fault_Handler, /* HardFault */
    Fault_Handler, /* MemManage */
    Fault_Handler, /* BusFault */
    Fault_Handler, /* UsageFault */
    0, 0, 0, 0,
    Fault_Handler, /* SVCall */
    Fault_Handler, /* DebugMon */
    0,
    Fault_Handler, /* PendSV */
    Fault_Handler, /* SysTick */
};

/* Paints the stack below the current frame so the driver can measure its high-water mark. */
void harness_paint_stack(void);

void Reset_Handler(void)
{
    uint32_t *src = &__data_load;
    for (uint32_t *dst = &__data_start; dst < &__data_end;)
        *dst++ = *src++;
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20; /* CPACR: CP10, CP11 full access */
    __asm volatile("dsb\n\tisb" ::: "memory");
    _start();
    for (;;) {
    }
}

void Fault_Handler(void)
{
    /* SYS_EXIT (0x18) with ADP_Stopped_RunTimeErrorUnknown: QEMU exits with status 1. */
    __asm volatile("movs r0, #0x18\n\t"
                   "ldr r1, =0x20023\n\t"
                   "bkpt 0xab" ::: "r0", "r1", "memory");
    for (;;) {
    }
}
