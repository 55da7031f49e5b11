"""What a reader sees: terminal, Markdown and LaTeX tables, figures, progress lines."""
