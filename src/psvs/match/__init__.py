"""Correspondence on the complex image: the paper's seeded edge algorithm (III.3), automatic pairing of
every edge with its twin (asked first whether the image holds twins beyond chance), sub-pixel refinement,
and 3-D output."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "auto": ["MIN_TWIN_LAG_PX", "image_chance", "twin_lags"],
        "chance": ["Chance", "Elsewhere", "agreeing_rows", "seed_pair_stands"],
        "correspondence": ["MatchParams", "MatchResult", "automatic_match", "finish_pairs", "match_image",
                           "rows_unshown", "seed_rows", "unshown_rows_reason"],
        "edges": ["edge_pixels"],
        "export": ["result_to_dict", "write_csv", "write_json", "write_ply"],
        "figures": ["write_figures"],
        "pairs": ["EdgePair"],
        "seeded": ["match_seeded"],
    },
)
