/* simavr metadata in the .mmcu section (not loaded to flash): part and clock, so `simavr` and the
 * harness know what to simulate. C, because AVR_MCU uses C99 designated initialisers. */
#include <avr_mcu_section.h> /* simavr-avr (pkg-config): -I/usr/include/simavr/avr */

AVR_MCU(F_CPU, "atmega328p");
