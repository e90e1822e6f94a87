"""Rubber backing sheets: Young's modulus from hardness and the compression modulus of a thin sheet.

A liner's rubber backing is a thin sheet between the liner plate and the mill shell. Pressed
through its thickness, a thin sheet cannot bulge much at its edges, so it is far stiffer than its
Young's modulus says; with a very large shape factor its stiffness approaches the bulk modulus.

- Young's modulus from the Shore A hardness H (A. N. Gent, Trans. Inst. Rubber Ind. 34 (1958)
  46-57): E = 0.0981 (56 + 7.62336 H) / (0.137505 (254 - 2.54 H)) MPa.
- Compression modulus of a sheet bonded to rigid plates (A. N. Gent and P. B. Lindley, Proc. Inst.
  Mech. Eng. 173 (1959) 111-122): E_a = E (1 + beta S^2) with beta = 2 for square or circular
  sheets, corrected for the bulk compressibility B: 1/E_c = 1/E_a + 1/B. S is the shape factor,
  the loaded area over the force-free (edge) area: a x b / (2 (a + b) t) for an a x b sheet of
  thickness t.
- The Winkler (bed-of-springs) stiffness of the sheet per area: k_n = E_c / t (Pa/m).
"""

from __future__ import annotations

import math

#: bulk modulus of natural-rubber compounds, Pa (P. B. Lindley, Engineering design with natural
#: rubber, MRPRA NR Technical Bulletin, 4th ed. 1978: about 2000 MPa, nearly independent of hardness)
RUBBER_BULK_MODULUS = 2.0e9
#: Gent and Lindley's beta for square or circular sheets
SHAPE_BETA = 2.0


def shore_a_modulus(hardness: float) -> float:
    """Young's modulus (Pa) of a rubber of Shore A ``hardness`` (Gent 1958, valid ~ 20-80 Shore A)."""
    if not (0.0 < hardness < 100.0):
        raise ValueError(f"Shore A hardness {hardness!r}: must lie in (0, 100)")
    return 1e6 * 0.0981 * (56.0 + 7.62336 * hardness) / (0.137505 * (254.0 - 2.54 * hardness))


def sheet_shape_factor(a: float, b: float, t: float) -> float:
    """Shape factor S = loaded area / force-free area = a b / (2 (a + b) t) of an a x b x t sheet (m)."""
    return a * b / (2.0 * (a + b) * t)


def compression_modulus(
    youngs: float, shape_factor: float, bulk: float = RUBBER_BULK_MODULUS, beta: float = SHAPE_BETA
) -> float:
    """Effective compression modulus E_c (Pa) of a bonded rubber sheet: 1/E_c = 1/(E (1 + beta S^2)) + 1/B
    (Gent and Lindley 1959)."""
    apparent = youngs * (1.0 + beta * shape_factor**2)
    return 1.0 / (1.0 / apparent + 1.0 / bulk)


def winkler_stiffness(modulus: float, thickness: float) -> float:
    """Normal stiffness per area k_n = E_c / t (Pa/m) of a layer of compression modulus E_c (Pa) and thickness t (m)."""
    if not (math.isfinite(modulus) and modulus > 0 and math.isfinite(thickness) and thickness > 0):
        raise ValueError("the backing's modulus and thickness must be > 0")
    return modulus / thickness
