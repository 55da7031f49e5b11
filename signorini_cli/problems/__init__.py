"""The problems: their spaces, forms, contact terms, manufactured data and measures."""
