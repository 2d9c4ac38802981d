//! Parametric families for the paper's 22 categories: a kit of parts
//! (`parts`) and one recipe per category (`furniture`, `small`), each drawing
//! its sizes, limits and colours from the instance's seeded RNG; training
//! instances also draw other mechanisms (`variants`) and glass (`glass`). Object
//! frame: origin on the floor at the footprint centre, z up, front face
//! toward -y (the camera).
mod furniture;
mod glass;
mod parts;
mod small;
mod variants;

use super::builder::Parts;
use super::{Category, GlassDraw};
use parts::{R, u};
use rand::Rng;

/// A training instance of these categories is, with this probability, one
/// of the mechanisms in `variants` instead of the category's recipe.
const VARIANT_SHARE: f64 = 0.4;

pub(crate) fn build(
    category: Category,
    rng: &mut R,
    test_instance: bool,
    glass: GlassDraw,
) -> Parts {
    let mut p = Parts::default();
    // The variant draw has its own stream: an instance that keeps its recipe
    // is the same object it was before the variants existed, and held-out
    // instances never draw (their figures are the paper recipes').
    let mut variant_rng = rng.clone();
    variant_rng.set_stream(1);
    let variant = !test_instance && variant_rng.random_bool(VARIANT_SHARE);
    // Glass has a stream of its own for the same reasons.
    let mut glass_rng = rng.clone();
    glass_rng.set_stream(2);
    match category {
        Category::StorageFurniture if variant => variants::flap_cabinet(&mut p, &mut variant_rng),
        Category::Window if variant => variants::hung_window(&mut p, &mut variant_rng),
        Category::Kettle if variant => variants::bail_kettle(&mut p, &mut variant_rng),
        Category::TrashCan if variant => variants::flap_lid_can(&mut p, &mut variant_rng),
        Category::Refrigerator => furniture::refrigerator(&mut p, rng),
        Category::FoldingChair => furniture::folding_chair(&mut p, rng),
        Category::Laptop => small::laptop(&mut p, rng),
        Category::Stapler => small::stapler(&mut p, rng),
        Category::TrashCan => small::trash_can(&mut p, rng),
        Category::Microwave => furniture::microwave(&mut p, rng),
        Category::Toilet => furniture::toilet(&mut p, rng),
        Category::Window => furniture::window(&mut p, rng),
        Category::StorageFurniture => furniture::cabinet(&mut p, rng),
        Category::Switch => small::switch(&mut p, rng),
        Category::Kettle => small::kettle(&mut p, rng),
        Category::Toy => small::toy(&mut p, rng, test_instance),
        Category::Box => {
            let dims = (u(rng, 0.4, 0.65), u(rng, 0.35, 0.5), u(rng, 0.25, 0.45));
            small::box_lid_family(&mut p, rng, dims, (1.6, 2.2))
        }
        Category::Phone => small::phone(&mut p, rng),
        Category::Dishwasher => furniture::dishwasher(&mut p, rng),
        Category::Safe => furniture::safe(&mut p, rng),
        Category::Oven => furniture::oven(&mut p, rng),
        Category::WashingMachine => furniture::washing_machine(&mut p, rng),
        Category::Table => furniture::table(&mut p, rng),
        Category::KitchenPot => small::kitchen_pot(&mut p, rng),
        Category::Bucket => small::bucket(&mut p, rng),
        Category::Door => furniture::door(&mut p, rng),
    }
    let glass_share = match glass {
        GlassDraw::Training if !test_instance => glass::GLASS_SHARE,
        GlassDraw::All => 1.0,
        _ => 0.0,
    };
    glass::glaze(category, &mut p, &mut glass_rng, glass_share);
    p
}
