//! The lexer: turns expression text into tokens, each with the character index where it
//! starts.
//!
//! Positions count Unicode characters (`char`s), not bytes, so that an error can point
//! at the right place in a formula written with, say, Greek letters.

use crate::expr::error::{shorten, Expected, ExprError};

/// The kinds of token.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum TokenKind<'a> {
    Number(f64),
    Ident(&'a str),
    Plus,
    Minus,
    Star,
    Slash,
    Caret,
    OpenParen,
    CloseParen,
    Comma,
    End,
}

/// A token, with its text and the character index where it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Token<'a> {
    pub(crate) kind: TokenKind<'a>,
    pub(crate) text: &'a str,
    pub(crate) position: usize,
}

impl Token<'_> {
    /// The error for this token appearing where `expected` was required.
    pub(crate) fn unexpected(&self, expected: Expected) -> ExprError {
        match self.kind {
            TokenKind::End => ExprError::UnexpectedEnd {
                expected,
                position: self.position,
            },
            _ => ExprError::UnexpectedToken {
                expected,
                found: shorten(self.text),
                position: self.position,
            },
        }
    }
}

/// A cursor over the text that knows both its byte offset and its character index.
pub(crate) struct Lexer<'a> {
    text: &'a str,
    byte: usize,
    position: usize,
}

impl<'a> Lexer<'a> {
    pub(crate) fn new(text: &'a str) -> Self {
        Lexer {
            text,
            byte: 0,
            position: 0,
        }
    }

    fn peek_char(&self) -> Option<char> {
        self.text[self.byte..].chars().next()
    }

    fn bump(&mut self) {
        if let Some(c) = self.peek_char() {
            self.byte += c.len_utf8();
            self.position += 1;
        }
    }

    fn bump_while(&mut self, keep: impl Fn(char) -> bool) {
        while self.peek_char().is_some_and(&keep) {
            self.bump();
        }
    }

    /// The error for the current character (or the end) when a digit was required.
    fn expected_digit(&self) -> ExprError {
        match self.peek_char() {
            None => ExprError::UnexpectedEnd {
                expected: Expected::Digit,
                position: self.position,
            },
            Some(c) => ExprError::UnexpectedToken {
                expected: Expected::Digit,
                found: c.to_string(),
                position: self.position,
            },
        }
    }

    /// Reads the next token, skipping whitespace before it.
    pub(crate) fn next_token(&mut self) -> Result<Token<'a>, ExprError> {
        self.bump_while(char::is_whitespace);
        let start_byte = self.byte;
        let position = self.position;
        let Some(c) = self.peek_char() else {
            return Ok(Token {
                kind: TokenKind::End,
                text: "",
                position,
            });
        };
        let kind = match c {
            '0'..='9' | '.' => self.number(position)?,
            c if c.is_alphabetic() || c == '_' => {
                self.bump_while(|c| c.is_alphanumeric() || c == '_');
                TokenKind::Ident(&self.text[start_byte..self.byte])
            }
            _ => {
                let kind = match c {
                    '+' => TokenKind::Plus,
                    '-' => TokenKind::Minus,
                    '*' => TokenKind::Star,
                    '/' => TokenKind::Slash,
                    '^' => TokenKind::Caret,
                    '(' => TokenKind::OpenParen,
                    ')' => TokenKind::CloseParen,
                    ',' => TokenKind::Comma,
                    character => {
                        return Err(ExprError::UnexpectedCharacter {
                            character,
                            position,
                        });
                    }
                };
                self.bump();
                kind
            }
        };
        Ok(Token {
            kind,
            text: &self.text[start_byte..self.byte],
            position,
        })
    }

    /// Reads `digits [. digits] [e|E [+|-] digits]` or `. digits [exponent]`.
    fn number(&mut self, position: usize) -> Result<TokenKind<'a>, ExprError> {
        let start_byte = self.byte;
        let is_digit = |c: char| c.is_ascii_digit();
        let int_start = self.byte;
        self.bump_while(is_digit);
        let has_int = self.byte > int_start;
        if self.peek_char() == Some('.') {
            self.bump();
            let frac_start = self.byte;
            self.bump_while(is_digit);
            if !has_int && self.byte == frac_start {
                return Err(self.expected_digit());
            }
        }
        if matches!(self.peek_char(), Some('e' | 'E')) {
            self.bump();
            if matches!(self.peek_char(), Some('+' | '-')) {
                self.bump();
            }
            let exp_start = self.byte;
            self.bump_while(is_digit);
            if self.byte == exp_start {
                return Err(self.expected_digit());
            }
        }
        let text = &self.text[start_byte..self.byte];
        // The text is ASCII digits, '.', 'e' and a sign in a shape Rust's correctly
        // rounding parser accepts; only overflow to infinity is refused.
        match text.parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(TokenKind::Number(value)),
            _ => Err(ExprError::NonFiniteConstant {
                text: shorten(text),
                position,
            }),
        }
    }
}
