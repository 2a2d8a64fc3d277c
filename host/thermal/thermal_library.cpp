// Anchor translation unit of btsm_thermal (the library must have a source of its own even when
// the inverse-heat sources are absent). Reports the library's version for diagnostics.
namespace btsm::thermal {
const char* thermal_library_name() { return "btsm_thermal"; }
}  // namespace btsm::thermal
