"""vpforms.symbolic — the SymPy layer: the 36 generating one-forms, their proofs, tables,
consistency of potentials, and the paper's errata, all computed from (σ, Σ).

``import vpforms.symbolic`` gives the whole layer (``import vpforms`` already loads SymPy: :class:`vpforms.Field`
and the method recipes use it).

* :func:`case_forms` — ν, ν̃, λ (LM normalisation), determining equations, twist conditions;
  :func:`identify_case` — the case of a given one-form λ = φ dx_l + Φ dX_m;
* :func:`prove_case`, :func:`prove_all` — f*ν̃ − ν = dλ on R⁶ and det Df = sign·sgnσ·sgnΣ;
* :func:`check_volpotinv`, :func:`check_permactalg`, :func:`check_trivperm`,
  :func:`check_switchperm` — the reduction propositions on generic potentials;
* :func:`table36_markdown`, :func:`table36_latex`, :func:`lm_tables_markdown`,
  :func:`lm_tables_latex` — rendering;
* :func:`consistency` — M(0) = I?, M'(0) = A?, order and det for given φ(h), Φ(h);
* :mod:`vpforms.symbolic.recipes` — the paper's potentials (printed and corrected), defined once,
  and :func:`to_generic` (LM/paper order → GeneratingMap order);
* :func:`errata_rows`, :func:`render_errata`, :func:`errata_report` — the measured errata.
"""

from . import recipes
from ._symbols import COORDS, A, X, Y, h, x, y
from .consistency import ConsistencyResult, consistency, generic_traceless_matrix
from .errata import ErrataRow, errata_report, errata_rows, render_errata
from .exterior import Form, d, dvar, wedge
from .forms import (
    CaseForms,
    CaseProof,
    case_forms,
    generic_equations,
    identify_case,
    lm_equations,
    prove_all,
    prove_case,
)
from .propositions import (
    PropositionCheck,
    check_permactalg,
    check_switchperm,
    check_trivperm,
    check_volpotinv,
)
from .recipes import (
    REPRESENTATIVES,
    SYMBOLS,
    GenericPotentials,
    Recipe,
    check_dependencies,
    dl_dl_potentials,
    dl_field_potentials,
    s1_potentials,
    s2_potentials,
    se_dl_potentials,
    se_field_potentials,
    se_se_potentials,
    to_generic,
)
from .tables import (
    lm_cell_latex,
    lm_table_cases,
    lm_tables_latex,
    lm_tables_markdown,
    table36_latex,
    table36_markdown,
    table36_rows,
)

__all__ = [
    "recipes",
    "COORDS", "A", "X", "Y", "h", "x", "y",
    "ConsistencyResult", "consistency", "generic_traceless_matrix",
    "ErrataRow", "errata_report", "errata_rows", "render_errata",
    "Form", "d", "dvar", "wedge",
    "CaseForms", "CaseProof", "case_forms", "generic_equations", "identify_case", "lm_equations",
    "prove_all",
    "prove_case",
    "PropositionCheck", "check_permactalg", "check_switchperm", "check_trivperm", "check_volpotinv",
    "REPRESENTATIVES", "SYMBOLS", "GenericPotentials", "Recipe", "check_dependencies",
    "dl_dl_potentials", "dl_field_potentials", "s1_potentials", "s2_potentials",
    "se_dl_potentials", "se_field_potentials", "se_se_potentials", "to_generic",
    "lm_cell_latex", "lm_table_cases", "lm_tables_latex", "lm_tables_markdown", "table36_latex",
    "table36_markdown", "table36_rows",
]
