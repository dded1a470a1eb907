"""The stability report: every stage of the data path for one scenario, as HTML and PDF."""

from .report import FORCE_TOLERANCE, Report, Verdict, build_report, write_report

__all__ = ["Verdict", "Report", "build_report", "write_report", "FORCE_TOLERANCE"]
