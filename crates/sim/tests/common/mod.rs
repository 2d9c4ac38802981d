//! Shared by the integration tests that compare the wgpu renderer with the
//! CPU ray caster.

/// Whether a wgpu adapter exists. Without one a comparison is skipped,
/// except under `UMPNET_REQUIRE_WGPU` or `CI=true`, where it fails: CI
/// installs Mesa's Vulkan driver, so a missing adapter there is a fault.
pub fn wgpu_present() -> bool {
    if umpnet_sim::render::gpu_available() {
        return true;
    }
    assert!(
        std::env::var_os("UMPNET_REQUIRE_WGPU").is_none()
            && std::env::var("CI").as_deref() != Ok("true"),
        "no wgpu adapter, under UMPNET_REQUIRE_WGPU or CI=true (install mesa-vulkan-drivers)"
    );
    eprintln!("skipped: no wgpu adapter");
    false
}
