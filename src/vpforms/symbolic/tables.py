"""Rendering: the 36-case table and the nine Lomelí–Meiss 2×2 tables, in Markdown and LaTeX.

Every entry is computed by :func:`vpforms.symbolic.case_forms` from (σ, Σ); the k = K = 0 LM
table reproduces the paper's Table tab:123123 cell by cell (function names A/B for φ in column
A/B, C/D for Φ in row C/D, arguments in sorted order as printed there).
"""

from __future__ import annotations

from collections.abc import Iterable

import sympy as sp

from .._case import CLASSES, Case, cases
from ._symbols import X, x
from .forms import CaseForms, case_forms, prove_case

__all__ = [
    "table36_rows",
    "table36_markdown",
    "table36_latex",
    "lm_table_cases",
    "lm_cell_latex",
    "lm_cell_markdown",
    "lm_tables_markdown",
    "lm_tables_latex",
]

_CLASS_DISPLAY = {"SE+DL": "SE+DL (=DL+SE)"}


def _name(s: sp.Symbol) -> str:
    return str(s)


def _tex(s: sp.Symbol) -> str:
    n = str(s)
    return f"{n[0]}_{n[1:]}"


def _sorted_args(args: Iterable[sp.Symbol]) -> list[sp.Symbol]:
    """The paper's order: lowercase by index, then uppercase by index."""
    order = list(x) + list(X)
    return sorted(args, key=order.index)


def _signed(c: int) -> str:
    return "" if c > 0 else "-"


def _perm_str(p) -> str:
    return p.one_line()


def _tau_str(cf: CaseForms) -> str:
    return f"{cf.tau.one_line()} = {cf.tau.cycle_notation()}"


def _nu_str(idx, letter: str, shift: int) -> str:
    a, b, c = idx
    return f"{letter}{c} d{letter}{a}^d{letter}{b} ({shift})"


def _ordered_cases() -> list[Case]:
    return sorted(cases(), key=lambda c: CLASSES.index(c.cls))


def table36_rows(prove: bool = True) -> list[dict[str, str]]:
    """One dict per case (ordered by class), with the columns of :func:`table36_markdown`.

    With ``prove=True`` the last column is ✓ only if :func:`prove_case` succeeded for the case.
    """
    rows = []
    for n, c in enumerate(_ordered_cases(), start=1):
        cf = case_forms(c)
        xp, xc, xm = map(_name, cf.x_roles)
        Xp, Xc, Xm = map(_name, cf.X_roles)
        lam = (
            f"phi({','.join(map(_name, cf.phi_args))}) d{xm} + "
            f"Phi({','.join(map(_name, cf.Phi_args))}) d{Xm}"
        )
        eqs = (
            f"{xp} = {_signed(cf.c_phi)}∂_{xc}phi ; ∂_{Xm}phi = ∂_{xm}Phi ; "
            f"{Xp} = {_signed(cf.c_Phi)}∂_{Xc}Phi"
        )
        proof = ("✓" if prove_case(c).holds else "✗") if prove else ""
        rows.append(
            {
                "#": str(n),
                "class": _CLASS_DISPLAY.get(c.cls, c.cls),
                "σ": _perm_str(c.sigma),
                "Σ": _perm_str(c.Sigma),
                "τ": _tau_str(cf),
                "sgn τ": f"{cf.sign:+d}",
                "ν (k)": _nu_str(cf.nu, "x", cf.k),
                "ν̃ (K)": _nu_str(cf.nu_tilde, "X", cf.K),
                "LM cell": cf.cell,
                "λ": lam,
                "equations": eqs,
                "proof": proof,
            }
        )
    return rows


_HEADERS = {
    "#": "#",
    "class": "class",
    "σ": "σ=(σ(+),σ(∘),σ(−))",
    "Σ": "Σ=(Σ(+),Σ(∘),Σ(−))",
    "τ": "τ=σ⁻¹∘Σ",
    "sgn τ": "sgn τ",
    "ν (k)": "ν (k)",
    "ν̃ (K)": "ν̃ (K)",
    "LM cell": "LM cell",
    "λ": "λ (LM normalisation)",
    "equations": "determining equations",
    "proof": "dλ=f*ν̃−ν",
}


def table36_markdown(prove: bool = True) -> str:
    """The 36 cases as a Markdown table (same columns as the project's cross-check table)."""
    rows = table36_rows(prove)
    keys = list(_HEADERS)
    out = ["| " + " | ".join(_HEADERS[k] for k in keys) + " |"]
    out.append("|" + "---|" * len(keys))
    out += ["| " + " | ".join(r[k] for k in keys) + " |" for r in rows]
    return "\n".join(out) + "\n"


def _lam_tex(cf: CaseForms, phi_name: str = r"\phi", Phi_name: str = r"\Phi",
             sort: bool = False) -> tuple[str, str]:
    pa = _sorted_args(cf.phi_args) if sort else cf.phi_args
    Pa = _sorted_args(cf.Phi_args) if sort else cf.Phi_args
    xm, Xm = cf.x_roles[2], cf.X_roles[2]
    return (
        f"{phi_name}({', '.join(map(_tex, pa))}) d{_tex(xm)}",
        f"{Phi_name}({', '.join(map(_tex, Pa))}) d {_tex(Xm)}",
    )


def _eqs_tex(cf: CaseForms, phi_name: str, Phi_name: str) -> list[str]:
    xp, xc, xm = map(_tex, cf.x_roles)
    Xp, Xc, Xm = map(_tex, cf.X_roles)
    return [
        rf"{xp}={_signed(cf.c_phi)}\partial_{{{xc}}}{phi_name}",
        rf"\partial_{{{Xm}}} {phi_name} = \partial_{{{xm}}} {Phi_name}",
        rf"{Xp} = {_signed(cf.c_Phi)}\partial_{{{Xc}}} {Phi_name}",
    ]


def _twist_tex(cf: CaseForms) -> str:
    xp, _, xm = map(_tex, cf.x_roles)
    Xp, _, Xm = map(_tex, cf.X_roles)
    return (
        rf"\frac{{\partial {Xm}}}{{\partial {xp}}} \not=0, \quad "
        rf"\frac{{\partial {xm}}}{{\partial {Xp}}} \not=0"
    )


def table36_latex(prove: bool = True) -> str:
    """The 36 cases as a LaTeX ``longtable`` (needs the longtable package)."""
    lines = [
        r"\begin{longtable}{r l c c c c c c c l l}",
        r"\# & class & $\sigma$ & $\Sigma$ & $\tau$ & $\operatorname{sgn}\tau$ & $\nu$ & "
        r"$\tilde\nu$ & cell & $\lambda$ & determining equations \\ \hline",
    ]
    for r, c in zip(table36_rows(prove), _ordered_cases()):
        cf = case_forms(c)
        a, b, cc = cf.nu
        A, B, C = cf.nu_tilde
        l1, l2 = _lam_tex(cf)
        lines.append(
            " & ".join(
                [
                    r["#"],
                    r["class"],
                    f"${r['σ']}$",
                    f"${r['Σ']}$",
                    f"${cf.tau.one_line()}$",
                    f"${cf.sign:+d}$",
                    f"$x_{cc}\\,dx_{a}\\wedge dx_{b}$",
                    f"$X_{C}\\,dX_{A}\\wedge dX_{B}$",
                    cf.cell,
                    f"${l1} + {l2}$",
                    "$" + r";\ ".join(_eqs_tex(cf, r"\phi", r"\Phi")) + "$",
                ]
            )
            + r" \\"
        )
    lines.append(r"\end{longtable}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------------
# The nine Lomelí–Meiss tables
# ------------------------------------------------------------------------------------------------
def lm_table_cases(k: int, K: int) -> dict[str, Case]:
    """The four cases of the LM table (k, K), keyed by cell "AC", "BC", "AD", "BD"."""
    out = {}
    for c in cases():
        cf = case_forms(c)
        if (cf.k, cf.K) == (k, K):
            out[cf.cell] = c
    if sorted(out) != ["AC", "AD", "BC", "BD"]:  # pragma: no cover - would be a bug
        raise AssertionError(f"LM table ({k},{K}) has cells {sorted(out)}")
    return out


def _cell_names(cf: CaseForms) -> tuple[str, str]:
    return cf.cell[0], cf.cell[1]


def lm_cell_latex(case: Case | tuple) -> str:
    """One cell of an LM table in the layout of Table tab:123123 (an ``array``)."""
    cf = case_forms(case)
    pn, Pn = _cell_names(cf)
    l1, l2 = _lam_tex(cf, pn, Pn, sort=True)
    e1, e2, e3 = _eqs_tex(cf, pn, Pn)
    return "\n".join(
        [
            r"\begin{array}{ccc}",
            rf"\lambda = {l1} \\",
            rf"\qquad \quad \mbox{{}}+ {l2}\\[5pt]",
            rf"{e1} \\",
            rf"{e2}\\",
            rf"{e3}\\",
            _twist_tex(cf),
            r"\end{array}",
        ]
    )


def lm_cell_markdown(case: Case | tuple) -> str:
    cf = case_forms(case)
    pn, Pn = _cell_names(cf)
    xp, xc, xm = map(_name, cf.x_roles)
    Xp, Xc, Xm = map(_name, cf.X_roles)
    pa = ",".join(map(_name, _sorted_args(cf.phi_args)))
    Pa = ",".join(map(_name, _sorted_args(cf.Phi_args)))
    t1, t2 = cf.twist_conditions()
    return "<br>".join(
        [
            f"λ = {pn}({pa}) d{xm} + {Pn}({Pa}) d{Xm}",
            f"{xp} = {_signed(cf.c_phi)}∂_{xc}{pn}",
            f"∂_{Xm}{pn} = ∂_{xm}{Pn}",
            f"{Xp} = {_signed(cf.c_Phi)}∂_{Xc}{Pn}",
            f"{t1}, {t2}",
        ]
    )


def _heading(k: int, K: int) -> tuple[CaseForms, tuple[int, int, int], tuple[int, int, int]]:
    cf = case_forms(lm_table_cases(k, K)["AC"])
    return cf, cf.nu, cf.nu_tilde


def lm_tables_markdown() -> str:
    """The nine LM 2×2 tables (k, K = 0, 1, 2) as Markdown."""
    out = []
    for k in range(3):
        for K in range(3):
            cells = lm_table_cases(k, K)
            _, (a, b, c), (A, B, C) = _heading(k, K)
            out.append(f"### ν = x{c} dx{a}∧dx{b} (k = {k}), ν̃ = X{C} dX{A}∧dX{B} (K = {K})\n")
            out.append(f"| X{C} dX{A}∧dX{B} − x{c} dx{a}∧dx{b} | A dx{a} | B dx{b} |")
            out.append("|---|---|---|")
            out.append(f"| C dX{A} | {lm_cell_markdown(cells['AC'])} | {lm_cell_markdown(cells['BC'])} |")
            out.append(f"| D dX{B} | {lm_cell_markdown(cells['AD'])} | {lm_cell_markdown(cells['BD'])} |")
            out.append("")
    return "\n".join(out)


def lm_tables_latex() -> str:
    """The nine LM 2×2 tables as LaTeX ``tabular``s in the layout of Table tab:123123."""
    out = []
    for k in range(3):
        for K in range(3):
            cells = lm_table_cases(k, K)
            _, (a, b, c), (A, B, C) = _heading(k, K)
            out += [
                r"\begin{table}[t]",
                r"\centering",
                r"  \begin{tabular}{ l | c | c | }",
                rf"  $X_{C} dX_{A} \wedge dX_{B}$ $-$ && \\",
                rf"  \quad $x_{c} dx_{a} \wedge dx_{b}$ & $A dx_{a}$& $B dx_{b}$\\  \hline",
                rf"    $C dX_{A}$ & ${lm_cell_latex(cells['AC'])} $ &  ${lm_cell_latex(cells['BC'])} $\\ \hline",
                rf"    $D d X_{B}$ & ${lm_cell_latex(cells['AD'])} $ &  ${lm_cell_latex(cells['BD'])} $\\",
                r"    \hline",
                r"  \end{tabular}",
                rf"  \caption{{Generating one-forms for $\nu = x_{c} dx_{a}\wedge dx_{b}$ ($k={k}$), "
                rf"$\tilde\nu = X_{C} dX_{A}\wedge dX_{B}$ ($K={K}$).}}",
                r"\end{table}",
                "",
            ]
    return "\n".join(out)
